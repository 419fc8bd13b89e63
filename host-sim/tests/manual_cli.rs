//! Moving slaves by hand from the command line, against `host-sim serve --pty` (each step
//! a `host-sim` process): an S-curve move that returns when the slave is there, a jog for
//! a set time, the deadman when the jogging process is killed, moves and jogs refused in
//! words, and `start --approach` from off the table to following.

mod common;
use common::{cli, json, ok, pos, refused, serve};
use std::time::Duration;

#[test]
fn jog_move_deadman_and_approach() {
    let dir = tempfile::tempdir().expect("tempdir");
    let s = serve(&dir.path().join("flash.bin"));
    let table = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/tangent_board.csv");
    assert!(cli(&s, &["upload", table, "--activate", "--id", "5"])
        .status
        .success());

    // Unreferenced: a move is refused (a jog would be allowed, to find a home switch).
    let e = refused(&s, &["motion", "move", "--axis", "0", "--to-mm", "30"]);
    assert!(e.contains("slave 0 is not referenced"), "{e}");
    common::reference_where_they_are(&s);

    // A move returns when the slave is there.
    let x0 = pos(&s, 0);
    let to = format!("{:.3}", x0 + 5.0);
    let out = ok(
        &s,
        &[
            "motion", "move", "--axis", "0", "--to-mm", &to, "--vmax", "20",
        ],
    );
    assert!(out.contains("axis 0 at"), "{out}");
    let st = json(&ok(&s, &["status", "--json"]));
    assert_eq!(st["state"], "manual");
    assert_eq!(st["axes"][0]["manual"], "hold");
    let x = st["axes"][0]["pos_mm"].as_f64().expect("pos");
    assert!(
        (x - (x0 + 5.0)).abs() <= 0.05,
        "at {x}, wanted {}",
        x0 + 5.0
    );
    assert_eq!(st["inputs"]["valve_power"], true, "holding under control");

    // Outside the axis' limits, too fast, options that do not belong: refused in words.
    let e = refused(&s, &["motion", "move", "--axis", "0", "--to-mm", "600"]);
    assert!(e.contains("outside its limits"), "{e}");
    let e = refused(
        &s,
        &[
            "motion", "move", "--axis", "0", "--to-mm", "30", "--vmax", "5000",
        ],
    );
    assert!(e.contains("max_speed"), "{e}");
    let e = refused(&s, &["motion", "move", "--axis", "0", "--speed-mm-s", "3"]);
    assert!(e.contains("does not take"), "{e}");
    let e = refused(
        &s,
        &[
            "motion",
            "jog",
            "--axis",
            "0",
            "--speed-mm-s",
            "1",
            "--jerk",
            "0",
        ],
    );
    assert!(e.contains("--jerk 0"), "{e}");

    // A jog for 0.6 s at −5 mm/s: about 3 mm down, then at rest.
    let y0 = pos(&s, 1);
    let out = ok(
        &s,
        &[
            "motion",
            "jog",
            "--axis",
            "1",
            "--speed-mm-s",
            "-5",
            "--seconds",
            "0.6",
        ],
    );
    assert!(out.contains("axis 1 at rest at"), "{out}");
    let dy = pos(&s, 1) - y0;
    assert!((-4.0..-2.0).contains(&dy), "jogged {dy} mm");

    // The deadman: a jog whose process dies stops within the deadman plus braking.
    let mut a = vec![
        "motion",
        "jog",
        "--axis",
        "1",
        "--speed-mm-s",
        "5",
        "--port",
    ];
    a.push(&s.1);
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(&a)
        .stdout(std::process::Stdio::null())
        .spawn()
        .expect("jog runs");
    std::thread::sleep(Duration::from_millis(800));
    child.kill().expect("kill");
    let _ = child.wait();
    std::thread::sleep(Duration::from_millis(700));
    let st = json(&ok(&s, &["status", "--json"]));
    assert_eq!(st["axes"][1]["manual"], "hold", "stopped by the deadman");
    let y1 = st["axes"][1]["pos_mm"].as_f64().expect("pos");
    std::thread::sleep(Duration::from_millis(300));
    assert!((pos(&s, 1) - y1).abs() < 0.05, "and stays");

    // Start --approach from off the table: the slaves move to it, then follow.
    let out = ok(&s, &["motion", "start", "--approach", "--vmax", "20"]);
    assert!(out.contains("following after"), "{out}");
    let st = json(&ok(&s, &["status", "--json"]));
    assert_eq!(st["state"], "following");
    for k in 0..2 {
        let e = st["axes"][k]["error_mm"].as_f64().expect("error");
        assert!(
            e.abs() < 0.2,
            "axis {k} error {e} mm right after the approach"
        );
    }
    // While following, manual motion is refused.
    let e = refused(&s, &["motion", "jog", "--axis", "0", "--speed-mm-s", "1"]);
    assert!(e.contains("following"), "{e}");
    ok(&s, &["motion", "stop"]);
}
