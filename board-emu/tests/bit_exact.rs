//! Bit-exact: the DAC codes the emulated firmware writes, tick for tick, equal the host
//! runtime's (`hydra_core::Runtime` with the board's profile) fed the same encoder counts
//! the firmware read — the same fixed-point code on the host and on the target.

mod common;

use common::*;
use hydra_core::dac::DacRange;
use hydra_core::follower::Follower;
use hydra_core::profile;
use hydra_core::runtime::encoder::{counts_from_u32, Extender16};
use hydra_core::runtime::{BootCause, Command, EncoderSample, Runtime, Sample};
use hydra_core::units::{PosUm, PressureBar};

#[test]
fn the_firmware_writes_the_host_runtimes_dac_codes_tick_for_tick() {
    let scn = scenario();
    let mut s = session(table(&scn));
    s.m.state_mut().bus.tick_io = Some(Vec::new());
    s.m.run_for(0.02).expect("boot");
    s.upload_activate(9).expect("upload");
    let nodes = s.nodes();
    let pos_um = s.plant.borrow().positions_um.clone();
    s.reference_and_start().expect("start");
    s.m.run_for(8.0).expect("follow");
    let io = s.m.state().bus.tick_io.clone().expect("recorded");
    let k_start = io
        .iter()
        .position(|t| t.enable == Some(true))
        .expect("the enable went high at Start");
    assert!(k_start > 2);

    // The host runtime with the board's profile and the same table.
    let range = DacRange::new(profile::VDDA_MV, profile::DAC_SWING_MARGIN_MV).expect("range");
    let mut law: Box<Follower<{ profile::SLAVES }, { profile::TABLE_NODES }>> =
        Box::new(Follower::unconfigured());
    law.configure(&profile::follower_config(range.max_code().unsigned_abs()))
        .expect("follower config");
    law.rebuild_table_from_nodes(&nodes, &profile::table_limits())
        .expect("table");
    let coeffs = profile::runtime_config().build().expect("runtime config");
    let mut rt: Runtime<_, { profile::SLAVES }, 4> = Runtime::new(coeffs, None, BootCause::Normal);
    rt.install(law).expect("install");
    let first3 = io[0].enc[2].expect("TIM3 read") as u16;
    let mut ext = Extender16::new(first3, 0);
    let mut compared = 0;
    for (k, t) in io.iter().enumerate() {
        let [Some(m), Some(a), Some(b)] = t.enc else {
            panic!("tick {k} did not read every encoder: {t:?}");
        };
        let sample = Sample {
            enc: EncoderSample {
                master: counts_from_u32(m),
                slaves: [counts_from_u32(a), ext.update(b as u16)],
                master_edges: None,
            },
            pressure_bar: [PressureBar::ZERO; 4],
            estop: false,
            overrun: false,
        };
        // The commands the board applied: set-position of both slaves just before Start,
        // Start at the tick that powered the valves.
        let cmd = match k.checked_sub(k_start - 2) {
            Some(0) | Some(1) => {
                let axis = (k + 2 - k_start) as u8;
                let p = pos_um.get(usize::from(axis)).copied().unwrap_or(0.0);
                Some(Command::SetPosition {
                    axis,
                    pos_um: PosUm::from_bits((p * 256.0).round() as i32),
                })
            }
            Some(2) => Some(Command::Start),
            _ => None,
        };
        let out = rt.step(&sample, cmd);
        if let Some(r) = out.reply {
            assert_eq!(r, Ok(()), "tick {k}: {cmd:?}");
        }
        let want = out.dac.map(|c| range.clamp(c).to_unipolar());
        assert_eq!(
            t.dac,
            [Some(want[0]), Some(want[1])],
            "tick {k} (Start at {k_start})"
        );
        assert_eq!(t.enable, Some(out.enable), "tick {k} enable");
        compared += 1;
    }
    eprintln!(
        "{compared} ticks bit-exact ({} following)",
        compared - k_start
    );
    assert!(compared - k_start > 7000);
}
