//! Bit-exact: the DAC codes the emulated firmware writes, tick for tick, equal the host
//! runtime's (`hydra_core::Runtime` with the board's profile) fed the same encoder counts
//! the firmware read (and the master edge timer's captures, extended and paired as
//! `firmware/src/edge_timer.rs` does) — the same fixed-point code on the host and on the
//! target.

mod common;

use common::*;
use hydra_core::dac::DacRange;
use hydra_core::follower::Follower;
use hydra_core::master::{EdgeCapture, EdgeReading};
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
    let first8 = io[0].edge_now.expect("TIM8 read") as u16;
    let mut clock = Extender16::new(first8, 0);
    let mut compared = 0;
    let mut edges = 0;
    let mut pairs: Vec<(u32, i32)> = Vec::new();
    for (k, t) in io.iter().enumerate() {
        let [Some(m), Some(a), Some(b)] = t.enc else {
            panic!("tick {k} did not read every encoder: {t:?}");
        };
        let now = clock
            .update(t.edge_now.expect("the tick read TIM8") as u16)
            .0 as u32;
        let edge = match (t.edge_time, t.edge_count) {
            ([Some(t0), Some(t1)], Some(c)) if t0 == t1 => Some(EdgeCapture {
                at_ticks: clock.extend_past(t0 as u16).0 as u32,
                count: counts_from_u32(c),
            }),
            _ => None,
        };
        edges += usize::from(edge.is_some());
        if let Some(e) = edge {
            pairs.push((e.at_ticks, e.count.0));
        }
        let sample = Sample {
            enc: EncoderSample {
                master: counts_from_u32(m),
                slaves: [counts_from_u32(a), ext.update(b as u16)],
                master_edges: Some(EdgeReading {
                    now_ticks: now,
                    edge,
                }),
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
        "{compared} ticks bit-exact ({} following, {edges} with a master edge captured)",
        compared - k_start
    );
    assert!(compared - k_start > 7000);
    // 3 °/s, one rising A edge per 4 counts: an edge in most 1 ms ticks once moving.
    assert!(edges > 4000, "{edges} ticks with an edge");
    // The pairs are the master's: one edge per line (counts 4 apart, or a multiple), and
    // their times on a 1 MHz clock give the table's 3 °/s (3 000 counts/s ± 3 % ripple)
    // — a frozen, mis-clocked or mis-triggered edge timer fails here, not only the
    // bit-for-bit comparison (which would reproduce the firmware's wrong readings).
    let mut speeds: Vec<f64> = pairs
        .windows(2)
        .skip(pairs.len() / 4)
        .filter_map(|w| {
            let (dt, dc) = (w[1].0.wrapping_sub(w[0].0), w[1].1.wrapping_sub(w[0].1));
            assert_eq!(dc.rem_euclid(4), 0, "edges {w:?} not a whole line apart");
            (dt > 0).then(|| f64::from(dc) * 1e6 / f64::from(dt))
        })
        .collect();
    speeds.sort_by(f64::total_cmp);
    let median = speeds[speeds.len() / 2];
    assert!(
        (2_850.0..3_150.0).contains(&median),
        "median master speed from the edge pairs {median} counts/s"
    );
    eprintln!("the edge pairs give the master at {median:.1} counts/s (median)");
}
