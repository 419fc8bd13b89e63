use anyhow::Result;
use board_emu::bus::Still;
use board_emu::elf::Image;
use board_emu::flash::Flash;
use board_emu::machine::Machine;
use std::rc::Rc;

fn main() -> Result<()> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "target/thumbv7em-none-eabihf/release/firmware".into());
    let secs: f64 = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.1);
    let image = Rc::new(Image::load(std::path::Path::new(&path))?);
    let mut m = Machine::new(image, Flash::new(), Box::new(Still(Default::default())))?;
    let t0 = std::time::Instant::now();
    let r = m.run_for(secs);
    let mut h = board_emu::host::Host::new();
    println!("hello: {:?}", h.request(&mut m, &hydra_core::protocol::Request::Hello));
    println!("status: {:?}", h.request(&mut m, &hydra_core::protocol::Request::GetStatus));
    println!(
        "emulated {:.4} s in {:.3} s wall; {:?}",
        m.seconds(),
        t0.elapsed().as_secs_f64(),
        m.state().stats
    );
    for l in board_emu::rtt::decode(&m.image().bytes, &m.state().rtt)? {
        println!("{} {}", l.level, l.message);
    }
    r
}
