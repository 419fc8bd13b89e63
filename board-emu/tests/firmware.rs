//! The firmware's release ELF on the emulated board (board-emu), closed through the
//! plant: boot, the host link, follow/save/reboot, E-stop, watchdog, power cuts.

mod common;

use board_emu::machine::TIM7_EXC;
use board_emu::session::Session;
use common::*;
use hydra_core::protocol::diag::{take_capture_row, CaptureArmMsg};
use hydra_core::protocol::msg::INPUT_ESTOP;
use hydra_core::protocol::{Request, Response};
use hydra_core::runtime::{Trigger, FLAG_ESTOP, FLAG_VALVE_POWER, STATE_MASK};

fn ticks(s: &Session) -> u64 {
    s.m.state().stats.taken.get(&TIM7_EXC).copied().unwrap_or(0)
}

#[test]
fn boots_ticks_feeds_the_watchdog_and_keeps_the_valves_safe() {
    let mut s = session(table(&scenario()));
    s.plant.borrow_mut().record = true;
    s.m.run_for(0.02).expect("boot");
    let (t0, f0) = (ticks(&s), s.m.state().bus.iwdg.feeds);
    assert!(t0 > 0, "the tick runs 20 ms after power-on");
    s.m.run_for(0.1).expect("run");
    let (t1, f1) = (ticks(&s), s.m.state().bus.iwdg.feeds);
    assert!(
        (100..=101).contains(&(t1 - t0)),
        "{} ticks in 100 ms",
        t1 - t0
    );
    assert_eq!(f1 - f0, t1 - t0, "one watchdog feed per tick");
    // Valves at null (no table: mid-scale) and unpowered throughout.
    let sh = s.plant.borrow();
    assert!(sh.trace.len() > 100);
    for row in &sh.trace {
        assert_eq!(
            (row[4], row[5]),
            (0.0, 0.0),
            "u and enable at t = {} s",
            row[0]
        );
    }
    assert_eq!(sh.outputs.dac, [Some(2048), Some(2048)]);
    assert!(!sh.outputs.enable);
    drop(sh);
    let log = log(&s);
    assert!(
        log.iter()
            .any(|l| l.contains("hydra firmware: boot Normal")),
        "{log:?}"
    );
    assert!(
        log.iter()
            .any(|l| l.starts_with("WARN no valid table in flash")),
        "{log:?}"
    );
    assert_stack(&s);
}

#[test]
fn hello_info_and_status_over_the_emulated_uart() {
    let mut s = session(table(&scenario()));
    s.m.run_for(0.02).expect("boot");
    match s.host.request(&mut s.m, &Request::Hello).expect("Hello") {
        Response::Info(i) => {
            assert_eq!((i.axes, i.capacity_rows, i.period_us), (2, 256, 1000));
            assert_eq!(i.active_id, u32::MAX);
        }
        r => panic!("Hello answered {r:?}"),
    }
    let st = s.status().expect("status");
    assert_eq!((st.state, st.fault_code), (0, 0));
    assert!(st.ticks > 10);
    // The real board's master is an encoder: the virtual master's request is refused.
    let q = Request::VirtualMaster {
        op: 1,
        speed_scale: 0.0,
    };
    match s.host.request(&mut s.m, &q) {
        Ok(Response::Nak { nak, .. }) => {
            assert_eq!(nak.code, hydra_core::protocol::NakCode::NoVirtualMaster)
        }
        r => panic!("VirtualMaster answered {r:?}"),
    }
    assert_stack(&s);
}

/// Upload → Commit → Activate → Save → power cycle → boots the slot → reference → Start
/// → follows the reference machine's run with the plant in the loop; the figures within
/// 1.5× of `host-sim run`'s for the same scenario, table and period.
fn follow_after_reboot(table: host_sim::camfile::CamCsv, id: u32) -> (f64, f64, f64, f64) {
    let scn = scenario();
    let rows = table.master.len();
    let mut s = session(table.clone());
    s.m.run_for(0.02).expect("boot");
    s.upload_activate(id).expect("upload and activate");
    s.host.ack(&mut s.m, &Request::Save).expect("Save");
    let mut s = s.power_cycle().expect("power cycle");
    // Booting a saved table rebuilds it from its nodes before the tick starts: ≈ 45 ms
    // (181 rows) to ≈ 68 ms (256 rows) of emulated time.
    s.m.run_for(0.2).expect("reboot");
    let boot = s.m.state().stats.first_tick.expect("the tick runs") as f64 / 168e6;
    eprintln!(
        "{rows} rows: the tick starts {:.1} ms after power-on (slot validated and rebuilt)",
        boot * 1e3
    );
    assert!(boot < 0.15, "boot took {boot} s");
    let log = log(&s);
    assert!(
        log.iter()
            .any(|l| l.contains(&format!("table {id} ({rows} rows) from slot"))),
        "{log:?}"
    );
    match s.host.request(&mut s.m, &Request::Hello).expect("Hello") {
        Response::Info(i) => assert_eq!(i.active_id, id),
        r => panic!("{r:?}"),
    }
    // The board says which slot booted and why: the last save.
    let st = s.status().expect("status");
    assert!(st.boot_slot < 2, "booted slot {}", st.boot_slot);
    assert_eq!(
        st.boot_reason,
        hydra_core::protocol::BootReason::Newest as u8
    );
    // Every path of the settings tree reads back from the firmware.
    for pp in hydra_core::protocol::settings::all_paths(2) {
        let q = Request::GetParam {
            axis: pp.axis,
            param: pp.id as u8,
        };
        match s.host.request(&mut s.m, &q).expect("GetParam") {
            Response::Param { value, .. } => assert!(value.is_finite(), "{pp}"),
            r => panic!("{pp}: {r:?}"),
        }
    }
    s.reference_and_start().expect("start");
    s.m.run_for(scn.duration_s().expect("duration"))
        .expect("follow");
    let st = s.status().expect("status");
    assert_eq!(st.fault_code, 0, "no fault while following");
    assert_stack(&s);
    let e = s.plant.borrow().errors[0];
    let sim = host_sim::sim::run(
        &scn,
        &table,
        &host_sim::sim::RunSpec {
            controller: host_sim::scenario::Controller::Feedforward,
            period_us: 1000,
            trace_every_s: None,
        },
        &mut |_| {},
    )
    .expect("host-sim run");
    let (smax, srms) = match sim.axes[0].result {
        host_sim::sim::AxisResult::Follower {
            max_error_um,
            rms_error_um,
        } => (max_error_um, rms_error_um),
        _ => panic!("tangent is a follower"),
    };
    eprintln!(
        "{rows} rows: board {:.2} / {:.2} µm, host-sim run {smax:.2} / {srms:.2} µm",
        e.max,
        e.rms()
    );
    assert!(e.n > 20_000, "{} error samples", e.n);
    assert!(
        e.max <= 1.5 * smax,
        "max {:.2} µm vs host-sim {smax:.2}",
        e.max
    );
    // The board's RMS depends on the instant the run starts within the master's motion
    // (a few ms earlier or later: 0.55 … 0.71 µm on the 181-row table, measured by
    // delaying the start 0 … 25 ms; 256 rows: 0.71 against the simulator's 0.42), more
    // than the simulator's: hence 2×, not the max's 1.5×.
    assert!(
        e.rms() <= 2.0 * srms,
        "rms {:.2} µm vs host-sim {srms:.2}",
        e.rms()
    );
    (e.max, e.rms(), smax, srms)
}

#[test]
fn tangent_table_saved_rebooted_and_followed() {
    let scn = scenario();
    follow_after_reboot(table(&scn), 7);
}

#[test]
fn a_table_of_the_full_row_capacity_saved_rebooted_and_followed() {
    let scn = scenario();
    follow_after_reboot(resampled(&table(&scn), 256), 8);
}

#[test]
fn estop_nulls_the_valves_and_drops_the_enable_within_one_tick() {
    let mut s = session(table(&scenario()));
    s.m.state_mut().bus.tick_io = Some(Vec::new());
    s.m.run_for(0.02).expect("boot");
    s.upload_activate(3).expect("upload");
    s.reference_and_start().expect("start");
    s.m.run_for(2.0).expect("follow");
    let out = s.plant.borrow().outputs;
    assert!(out.enable, "following: valves powered");
    // The loop-rate capture armed on the E-stop's fault: 20 ticks either side.
    let arm = Request::CaptureArm(CaptureArmMsg::new(Trigger::Fault, 20, 20));
    assert!(matches!(
        s.host.request(&mut s.m, &arm),
        Ok(Response::Ack { .. })
    ));
    s.m.run_for(0.03).expect("30 ticks before the E-stop");
    let cut = s.m.cycles();
    s.plant.borrow_mut().estop_closed = false;
    s.m.run_for(0.003).expect("run");
    let io = s.m.state().bus.tick_io.clone().expect("recorded");
    let first = io
        .iter()
        .find(|t| t.at > cut)
        .expect("a tick after the E-stop");
    assert_eq!(
        first.enable,
        Some(false),
        "enable dropped by the first tick: {first:?}"
    );
    assert_eq!(
        first.dac,
        [Some(2048), Some(2048)],
        "valves at null: {first:?}"
    );
    assert!(first.at - cut <= 168_000, "within one period");
    let st = s.status().expect("status");
    assert_eq!(st.fault_code, 0x0100, "E-stop fault latched");
    assert_eq!(st.inputs, INPUT_ESTOP, "E-stop active, valve power off");
    assert!(
        st.axes.iter().all(|a| a.reference == 2),
        "both slaves referenced"
    );
    assert_eq!(st.active_rows as usize, s.nodes().len());
    // The history: the E-stop at the tick it latched, and the link's statistics.
    match s.host.request(&mut s.m, &Request::GetFaults) {
        Ok(Response::Faults(f)) => {
            let e = f.events.last().expect("an event");
            assert_eq!(e.code, 0x0100);
            assert!(f.link.frames > 10 && f.link.bad_frames == 0, "{:?}", f.link);
        }
        r => panic!("GetFaults answered {r:?}"),
    }
    // The capture, read back in frames once the 20 ticks after the trigger have run: the
    // trigger row is the E-stop tick.
    s.m.run_for(0.03).expect("run");
    let mut rows = Vec::new();
    let info = loop {
        let q = Request::GetCapture {
            offset: rows.len() as u32,
            count: 255,
        };
        let Ok(Response::Capture(c)) = s.host.request(&mut s.m, &q) else {
            panic!("GetCapture");
        };
        assert_eq!(c.phase, 3, "done 20 ticks after the fault");
        let mut r = hydra_core::protocol::wire::Reader::new(&c.data);
        while r.remaining() > 0 {
            rows.push(take_capture_row(&mut r, 2).expect("a whole row"));
        }
        if rows.len() as u32 >= c.rows {
            break c;
        }
    };
    assert_eq!((info.pre, info.rows), (20, 41));
    let (before, at) = (&rows[19], &rows[20]);
    assert_eq!(before.flags & STATE_MASK, 1, "following before the E-stop");
    assert_ne!(before.flags & FLAG_VALVE_POWER, 0);
    assert_eq!(at.flags & STATE_MASK, 3, "the trigger row is in Fault");
    assert_ne!(at.flags & FLAG_ESTOP, 0);
    assert_eq!(
        at.flags & FLAG_VALVE_POWER,
        0,
        "valve power off in that tick"
    );
    assert!(
        at.axes.iter().all(|a| a.dac == 0),
        "valves at null in that tick"
    );
    assert!(rows[..20].iter().all(|r| r.axes[0].pressure_cbar[0] > 0));
    assert_stack(&s);
}

#[test]
fn a_stalled_tick_is_reset_by_the_watchdog_and_boots_into_its_fault() {
    let mut s = session(table(&scenario()));
    s.m.run_for(0.03).expect("boot");
    s.m.state_mut().stall_tick = true;
    s.m.run_for(0.2).expect("stall and reset");
    assert_eq!(s.m.state().stats.watchdog_resets, 1, "one watchdog reset");
    let log = log(&s);
    assert!(log.iter().any(|l| l.contains("boot Watchdog")), "{log:?}");
    // A new session after the reset.
    assert!(matches!(
        s.host.request(&mut s.m, &Request::Hello),
        Ok(Response::Info(_))
    ));
    let st = s.status().expect("status");
    assert_eq!(st.state, 3, "boots into Fault");
    assert_eq!(st.fault_code, 0x0200, "the watchdog fault");
    assert_stack(&s);
}

#[test]
fn a_power_cut_at_twenty_points_of_a_save_always_boots_a_valid_table() {
    let scn = scenario();
    let t = table(&scn);
    // Flash with table 1 saved.
    let mut s = session(t.clone());
    s.m.run_for(0.02).expect("boot");
    s.upload_activate(1).expect("upload 1");
    s.host.ack(&mut s.m, &Request::Save).expect("Save 1");
    let saved = s.m.state().bus.flash.clone();
    // A Save of table 2, cut `cut_after` cycles after it was sent (None: not cut):
    // returns when it was sent, when its erase ended, its length and the flash.
    let save_of_2 = |cut_after: Option<u64>| -> (u64, u64, u64, board_emu::flash::Flash) {
        let mut s = Session::new(image(), saved.clone(), &scn, t.clone()).expect("session");
        s.m.run_for(0.2).expect("boot");
        s.upload_activate(2).expect("upload 2");
        let t0 = s.m.cycles();
        match cut_after {
            None => {
                s.host.ack(&mut s.m, &Request::Save).expect("Save 2");
                let erased =
                    s.m.state()
                        .bus
                        .flash
                        .erase_done_at
                        .expect("the Save erased");
                (t0, erased - t0, s.m.cycles() - t0, s.m.power_cut())
            }
            Some(dt) => {
                let mut buf = [0u8; 64];
                let n =
                    hydra_core::protocol::handler::encode_request(0x4000, &Request::Save, &mut buf)
                        .expect("frame");
                let now = s.m.cycles();
                s.m.state_mut().bus.usart6.host_send(&buf[..n], now);
                s.m.run_until(t0 + dt).expect("until the cut");
                (t0, 0, dt, s.m.power_cut())
            }
        }
    };
    let (_, erase, len, _) = save_of_2(None);
    assert!(
        erase > 168_000_000 / 2,
        "a Save erases a 128 KiB sector: {erase} cycles"
    );
    assert!(len > erase, "then programs the slot");
    // Ten cuts spread over the erase, ten over the programming that follows it.
    let cuts: Vec<u64> = (0..10u64)
        .map(|k| erase * (2 * k + 1) / 20)
        .chain((0..10u64).map(|k| erase + (len - erase) * (2 * k + 1) / 20))
        .collect();
    let mut booted = [0u32; 2];
    for (k, &dt) in cuts.iter().enumerate() {
        let (_, _, _, flash) = save_of_2(Some(dt));
        let mut s = Session::new(image(), flash, &scn, t.clone()).expect("session");
        s.m.run_for(0.2).expect("boot after the cut");
        let id = match s.host.request(&mut s.m, &Request::Hello).expect("Hello") {
            Response::Info(i) => i.active_id,
            r => panic!("{r:?}"),
        };
        assert!(
            id == 1 || id == 2,
            "cut {k} at {dt} cycles: booted table {id:#x}; {:?}",
            log(&s)
        );
        // A cut save never reads as complete: what booted is the newest complete one.
        let st = s.status().expect("status");
        assert!(st.boot_slot < 2, "cut {k}: booted slot {}", st.boot_slot);
        assert_eq!(
            st.boot_reason,
            hydra_core::protocol::BootReason::Newest as u8,
            "cut {k}"
        );
        booted[(id - 1) as usize] += 1;
        assert_stack(&s);
    }
    eprintln!("cuts booting table 1 / 2: {booted:?} (Save: erase {erase}, total {len} cycles)");
    assert!(
        booted[0] >= 10,
        "a cut during the erase keeps table 1: {booted:?}"
    );
}

#[test]
fn the_same_elf_and_inputs_give_the_same_run_bit_for_bit() {
    let run = || {
        let mut s = session(table(&scenario()));
        s.plant.borrow_mut().record = true;
        s.m.state_mut().bus.tick_io = Some(Vec::new());
        s.m.run_for(0.02).expect("boot");
        s.upload_activate(5).expect("upload");
        s.reference_and_start().expect("start");
        s.m.run_for(2.5).expect("follow");
        let trace: Vec<u64> = s
            .plant
            .borrow()
            .trace
            .iter()
            .flatten()
            .map(|v| v.to_bits())
            .collect();
        (
            s.m.cycles(),
            s.m.state().stats.instructions,
            trace,
            s.m.state().bus.tick_io.clone(),
        )
    };
    let (a, b) = (run(), run());
    assert_eq!(a.0, b.0);
    assert_eq!(a.1, b.1);
    assert!(a.2 == b.2, "traces differ");
    assert!(a.3 == b.3, "tick I/O differs");
}

#[test]
fn jog_move_deadman_and_approach_on_the_real_firmware() {
    use hydra_core::protocol::msg::MotionLimitsMsg;
    let limits = MotionLimitsMsg {
        vel_um_per_s: 20_000,
        acc_um_per_s2: 200_000,
        jerk_um_per_s3: 4_000_000,
    };
    let mut s = session(table(&scenario()));
    s.m.run_for(0.02).expect("boot");
    s.upload_activate(4).expect("upload");
    let st = s.status().expect("status");
    for (k, a) in st.axes.iter().enumerate() {
        let q = Request::SetPosition {
            axis: k as u8,
            pos_um: a.pos_um,
        };
        s.host.ack(&mut s.m, &q).expect("SetPosition");
    }
    // A 5 mm S-curve move of slave 0 (≈ 0.35 s): there, holding in Manual, no overrun.
    let to = st.axes[0].pos_um + (5000 << 8);
    let mv = Request::MoveTo {
        axis: 0,
        to_um: to,
        limits,
    };
    s.host.ack(&mut s.m, &mv).expect("MoveTo");
    s.m.run_for(0.1).expect("moving");
    let st = s.status().expect("status");
    assert_eq!((st.state, st.axes[0].manual), (4, 2), "manual, moving");
    s.m.run_for(1.0).expect("arrive");
    let st = s.status().expect("status");
    assert_eq!((st.state, st.axes[0].manual), (4, 0), "manual, holding");
    let off_um = f64::from(st.axes[0].pos_um - to).abs() / 256.0;
    assert!(off_um < 50.0, "{off_um} µm from the target");
    assert_eq!(st.overruns, 0);
    // Out of the axis' limits: refused, nothing moves.
    let far = Request::MoveTo {
        axis: 0,
        to_um: 600_000 << 8,
        limits,
    };
    assert!(matches!(
        s.host.request(&mut s.m, &far),
        Ok(Response::Nak { nak, .. }) if nak.code == hydra_core::protocol::NakCode::Motion
    ));
    // A jog renewed every 100 ms keeps going; without renewal the deadman stops it.
    // (Slave 0: the plant's slave 1 is not driven in this scenario — jogging it ends in
    // its following-error fault, as it should.)
    let jog = Request::Jog {
        axis: 0,
        speed: 5000 << 8,
        limits,
    };
    for _ in 0..5 {
        s.host.ack(&mut s.m, &jog).expect("Jog");
        s.m.run_for(0.1).expect("jogging");
    }
    let st = s.status().expect("status");
    assert_eq!(st.axes[0].manual, 1, "jogging");
    assert!(st.axes[0].pos_um > to + (1000 << 8), "moved up");
    s.m.run_for(0.3).expect("deadman");
    s.m.run_for(0.2).expect("braking");
    let st = s.status().expect("status");
    assert_eq!(
        (st.state, st.axes[0].manual),
        (4, 0),
        "stopped by the deadman"
    );
    assert_eq!(st.fault_code, 0);
    // Approach: both slaves to the table at the master (slave 0 ≈ 200 mm away: ≈ 2.1 s
    // at 100 mm/s), then following.
    let fast = MotionLimitsMsg {
        vel_um_per_s: 100_000,
        acc_um_per_s2: 1_000_000,
        jerk_um_per_s3: 20_000_000,
    };
    s.host
        .ack(&mut s.m, &Request::Approach { limits: fast })
        .expect("Approach");
    s.m.run_for(3.0).expect("approach");
    let st = s.status().expect("status");
    assert_eq!(
        st.state,
        1,
        "following after the approach: {:?}, master {}",
        st.axes,
        st.master >> 16
    );
    assert_eq!(st.fault_code, 0);
    let worst = st.axes.iter().map(|a| a.error_um.abs()).max().unwrap_or(0);
    assert!(worst < 200 << 8, "error {} µm", worst / 256);
    eprintln!(
        "manual: tick max {} ns, mean {} ns (the move's plan is made in the tick of its command)",
        st.tick_max_ns, st.tick_mean_ns
    );
    assert_eq!(st.overruns, 0);
    assert_stack(&s);
}

/// The real firmware follows `scn`'s table on its plant for the scenario's duration
/// after boot, upload, activation and the slave-0 settings `params` set over the link:
/// the Status then and slave 0's error statistics (the stack checked).
fn follow_on_board(
    scn: &host_sim::scenario::Scenario,
    params: &[(hydra_core::protocol::settings::ParamId, f32)],
) -> (
    hydra_core::protocol::msg::StatusMsg,
    host_sim::sim::ErrorStat,
) {
    let mut s =
        board_emu::session::Session::new(image(), board_emu::flash::Flash::new(), scn, table(scn))
            .expect("session");
    s.m.run_for(0.02).expect("boot");
    s.upload_activate(11).expect("upload and activate");
    for &(id, value) in params {
        let set = Request::SetParam {
            axis: 0,
            param: id as u8,
            value,
        };
        s.host.ack(&mut s.m, &set).expect("SetParam");
    }
    s.reference_and_start().expect("start");
    s.m.run_for(scn.duration_s().expect("duration"))
        .expect("follow");
    let st = s.status().expect("status");
    assert_stack(&s);
    let e = s.plant.borrow().errors[0];
    (st, e)
}

/// Active damping set over the link runs on the real firmware, where it matters: the
/// reference machine with aerated oil (bulk modulus ×0.5). The board follows the table
/// with ΔP feedback of `dp_gain` LSB/kN on slave 0 (the board's profile areas, the
/// chamber pressures the emulated ADC converts from the plant): the fault code latched
/// (0: none) and the max / RMS error, µm.
/// The soft machine's run: (fault code, max and RMS error µm, slave 0's backoff level
/// as Status reports it).
fn soft_machine_run(dp_gain: f32, osc_band_um: f32) -> (u16, f64, f64, u8) {
    use hydra_core::protocol::settings::ParamId;
    let mut scn = scenario();
    for a in &mut scn.axes {
        a.cylinder.bulk_modulus_pa *= 0.5;
    }
    let (st, e) = follow_on_board(
        &scn,
        &[
            (ParamId::DpGainLsbPerKn, dp_gain),
            (ParamId::OscBandUm, osc_band_um),
        ],
    );
    let backoff = st.axes.first().map_or(0, |a| a.backoff);
    eprintln!(
        "bulk ×0.5, dp_gain {dp_gain} LSB/kN, osc_band {osc_band_um} µm: fault {}, board {:.2} / {:.2} µm, backoff level {backoff}",
        st.fault_code,
        e.max,
        e.rms()
    );
    (st.fault_code, e.max, e.rms(), backoff)
}

/// Without the damping (and without the gain backoff, which would hold it: the next
/// test) the soft machine shakes until the following-error limit trips;
/// with it (60 LSB/kN) the same firmware holds it within 30 µm — so the firmware hands
/// the pressures to the law, and the law uses them. (The simulator, with a full period
/// of computation delay where the board writes its valves within the tick, holds it at
/// 20 LSB/kN; on the board 20 gives 179 µm and 60 is needed: docs/results.md,
/// "Active damping".)
#[test]
fn active_damping_set_over_the_link_holds_the_soft_machine_on_the_real_firmware() {
    let (fault_off, max_off, _, _) = soft_machine_run(0.0, 0.0);
    assert!(
        fault_off != 0 || max_off > 100.0,
        "undamped: fault {fault_off}, {max_off:.1} µm"
    );
    let (fault_on, max_on, rms_on, _) = soft_machine_run(60.0, 0.0);
    assert_eq!(fault_on, 0, "no fault with the damping");
    assert!(
        max_on < 30.0 && rms_on < 5.0,
        "{max_on:.1} / {rms_on:.2} µm"
    );
}

/// The gain backoff as shipped (the board's profile: 4 µm) on the real firmware holds
/// the soft machine that shakes into its following-error fault without it (previous
/// test): no fault, the error far below that fault's 5 mm, and Status names the level
/// the axis backed off to (measured: 12.0 / 1.22 µm).
#[test]
fn the_shipped_gain_backoff_holds_the_soft_machine_on_the_real_firmware() {
    let (fault, max, rms, level) = soft_machine_run(0.0, hydra_core::profile::OSC_BAND_UM);
    assert_eq!(
        fault, 0,
        "no fault with the backoff ({max:.1} / {rms:.2} µm)"
    );
    assert!(max < 30.0, "{max:.1} / {rms:.2} µm");
    assert!(level >= 1, "Status reports the backoff: level {level}");
}

/// The feed-forward trim as shipped (the board's profile: τ 1 s) on the real firmware: a
/// valve with 20 % more rated flow at 180 bar — 27 % more flow than the feed-forward's
/// calibration, the robustness box's fastest valve — is followed without a fault within
/// 30 µm, and Status reports the ratio the axis learned for each direction near 1/1.27
/// (host-sim on the same machine learns 0.78 both ways, `host-sim run --csv`:
/// `tangent_ff_trim_neg`, `_pos`).
#[test]
fn the_shipped_ff_trim_learns_the_valve_on_the_real_firmware() {
    let mut scn = scenario();
    scn.supply.supply_bar = 180.0;
    for a in &mut scn.axes {
        a.valve.rated_flow_l_per_min *= 1.2;
    }
    let (st, e) = follow_on_board(&scn, &[]);
    let trim = st.axes.first().map_or([0; 2], |a| a.ff_trim);
    eprintln!(
        "flow ×1.2 at 180 bar: fault {}, board {:.2} / {:.2} µm, Status ff_trim {trim:?} (ratio − 1, 1/10 000)",
        st.fault_code,
        e.max,
        e.rms()
    );
    assert_eq!(st.fault_code, 0, "no fault");
    assert!(e.max < 30.0, "{:.1} µm", e.max);
    for t in trim {
        assert!((-2_700..=-1_700).contains(&t), "learned {trim:?}");
    }
}
