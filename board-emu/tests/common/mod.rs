//! Shared set-up of the firmware-in-the-loop tests: the release ELF, the reference
//! machine (tangent_alone.toml) and its table.

#![allow(dead_code)]

use board_emu::elf::Image;
use board_emu::flash::Flash;
use board_emu::session::Session;
use host_sim::camfile::CamCsv;
use host_sim::scenario::Scenario;
use std::path::PathBuf;
use std::rc::Rc;

/// The workspace root.
pub fn root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// The firmware's release ELF (ci.sh builds it before these tests run).
pub fn image() -> Rc<Image> {
    let target =
        std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root().join("target"), PathBuf::from);
    let p = target.join("thumbv7em-none-eabihf/release/firmware");
    assert!(
        p.exists(),
        "{} is missing: build it first (cargo build -p firmware --release --target thumbv7em-none-eabihf)",
        p.display()
    );
    Rc::new(Image::load(&p).expect("the firmware ELF loads"))
}

/// The one-axis reference machine.
pub fn scenario() -> Scenario {
    Scenario::load(&root().join("host-sim/scenarios/tangent_alone.toml")).expect("scenario")
}

/// Its cam table (181 rows).
pub fn table(scn: &Scenario) -> CamCsv {
    scn.load_table(None).expect("table")
}

/// The tangent table resampled (linearly) to `rows` nodes over the same master range.
pub fn resampled(t: &CamCsv, rows: usize) -> CamCsv {
    let (a, b) = (t.master[0], t.master[t.master.len() - 1]);
    let mut out = t.clone();
    out.master = (0..rows)
        .map(|k| a + (b - a) * k as f64 / (rows - 1) as f64)
        .collect();
    out.columns = t
        .columns
        .iter()
        .map(|c| {
            let mut hint = 0;
            out.master
                .iter()
                .map(|&m| host_sim::camfile::interpolate(&t.master, c, m, &mut hint))
                .collect()
        })
        .collect();
    out.lines = (2..rows + 2).collect();
    out
}

/// A board powered on with an erased flash.
pub fn session(table: CamCsv) -> Session {
    let scn = scenario();
    Session::new(image(), Flash::new(), &scn, table).expect("session")
}

/// The decoded log.
pub fn log(s: &Session) -> Vec<String> {
    board_emu::rtt::decode(&s.m.image().bytes, &s.m.state().rtt)
        .expect("defmt log decodes")
        .into_iter()
        .map(|l| format!("{} {}", l.level, l.message))
        .collect()
}

/// Free stack bytes never touched: at least 8 KiB in every test.
pub fn assert_stack(s: &Session) {
    let free = s.m.stack_min_free();
    assert!(free >= 8 * 1024, "stack high-water leaves only {free} B");
}
