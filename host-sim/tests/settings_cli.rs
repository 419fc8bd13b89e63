//! The settings tree from the command line, against `host-sim serve --pty --flash FILE`
//! run as a user runs it (every step a `host-sim` process): settings saved alone before
//! any table and back after a restart; settings set in any order,
//! saved and read back exactly after a restart of `serve` on the same flash file; every
//! path of `param list` read back with `param get`; a committed table that the settings
//! in force make invalid cannot be activated; bad paths and values are refused naming
//! the path.

mod common;
use common::{json, ok, refused, serve};
use std::path::Path;

/// A flat table: slave 0 at `x_mm`, slave 1 (the side press) at 20 mm.
fn table(dir: &Path, name: &str, x_mm: f64) -> String {
    let p = dir.join(name);
    let rows: String = (0..3).map(|m| format!("{m},{x_mm},20\n")).collect();
    std::fs::write(&p, format!("master,x,press\n{rows}")).expect("write csv");
    p.display().to_string()
}

#[test]
fn settings_survive_a_restart_exactly_and_every_path_reads_back() {
    let dir = tempfile::tempdir().expect("tempdir");
    let flash = dir.path().join("board.flash");
    let b = serve(&flash);

    // Every path of `list` reads back with `get`, with its unit and range.
    let list = json(&ok(&b, &["param", "list", "--json"]));
    let rows = list.as_array().expect("array");
    assert_eq!(
        rows.len(),
        43 * 2 + 11,
        "43 settings per slave, 11 board-wide"
    );
    for r in rows {
        let path = r["path"].as_str().expect("path");
        assert!(r["unit"].is_string() && r["min"].is_number() && r["max"].is_number());
        let g = json(&ok(&b, &["param", "get", path, "--json"]));
        assert_eq!(g["path"], r["path"]);
        assert_eq!(g["value"], r["value"], "{path}");
    }

    // Settings alone, before any table (a valve calibration at commissioning): saved,
    // and back after a restart with no table running.
    ok(&b, &["param", "set", "axis/1/valve/null_lsb", "-12.5"]);
    ok(&b, &["param", "save"]);
    drop(b);
    let b = serve(&flash);
    let v = json(&ok(
        &b,
        &["param", "get", "axis/1/valve/null_lsb", "--json"],
    ));
    assert_eq!(v["value"], -12.5);
    let st = json(&ok(&b, &["status", "--json"]));
    assert_eq!(
        (st["active_id"].is_null(), st["boot_reason"].as_str()),
        (true, Some("newest"))
    );

    // Settings in any order: min 100 mm, max 700 mm, then min 250 mm (validated as a
    // set, never replayed one by one); the two Kv set separately; a boolean by name.
    for (path, v) in [
        ("axis/0/limits/min_um", "100000"),
        ("axis/0/limits/max_um", "700000"),
        ("axis/0/limits/min_um", "250000"),
        ("axis/0/kv_pos_lsb_per_um_s", "0.0125"),
        ("axis/0/kv_neg_lsb_per_um_s", "0.0150"),
        ("axis/1/valve/null_lsb", "-12.5"),
        ("axis/1/valve/invert", "true"),
        ("link/timeout_ms", "0"),
        // Active damping on slave 0 (the board's profile holds the cylinder's areas).
        ("axis/0/dp_gain_lsb_per_kn", "20"),
    ] {
        let set = json(&ok(&b, &["param", "set", path, v, "--json"]));
        assert_eq!(set["path"], path);
    }
    let get = |path: &str| json(&ok(&b, &["param", "get", path, "--json"]))["value"].clone();
    assert_eq!(get("axis/0/kv_pos_lsb_per_um_s"), 0.0125);
    assert_eq!(get("axis/0/kv_neg_lsb_per_um_s"), 0.015);
    assert_eq!(get("axis/1/valve/invert"), 1.0);
    assert_eq!(get("axis/0/dp_gain_lsb_per_kn"), 20.0);
    assert_eq!(get("axis/0/cylinder/area_a_mm2"), 5026.5);

    // Bad input: named, nothing changed.
    let e = refused(&b, &["param", "set", "axis/0/kp", "1"]);
    assert!(e.contains("axis/0/kp") && e.contains("param list"), "{e}");
    let e = refused(&b, &["param", "set", "axis/0/valve/null_lsb", "900"]);
    assert!(
        e.contains("axis/0/valve/null_lsb") && e.contains("500"),
        "{e}"
    );
    let e = refused(&b, &["param", "set", "axis/0/dp_gain_lsb_per_kn", "2000"]);
    assert!(
        e.contains("axis/0/dp_gain_lsb_per_kn") && e.contains("1000"),
        "{e}"
    );
    let e = refused(&b, &["param", "set", "period_us", "500"]);
    assert!(e.contains("read-only"), "{e}");
    // min above max: in range alone, refused by the board as a set, naming the path.
    let e = refused(&b, &["param", "set", "axis/0/limits/min_um", "800000"]);
    assert!(e.contains("axis/0/limits/min_um"), "{e}");
    assert_eq!(get("axis/0/limits/min_um"), 250000.0);

    // Table 1 at 300 mm runs; table 2 at 650 mm is committed; then the maximum drops to
    // 600 mm (legal for the active table): table 2 can no longer be activated.
    let t1 = table(dir.path(), "t1.csv", 300.0);
    let t2 = table(dir.path(), "t2.csv", 650.0);
    ok(&b, &["upload", &t1, "--id", "1", "--activate"]);
    ok(&b, &["upload", &t2, "--id", "2"]);
    let tables = json(&ok(&b, &["table", "list", "--json"]));
    assert_eq!(
        (tables["active"].clone(), tables["committed"].clone()),
        (1.into(), 2.into())
    );
    ok(&b, &["param", "set", "axis/0/limits/max_um", "600000"]);
    let e = refused(&b, &["table", "activate", "--id", "2"]);
    assert!(e.contains("outside the slave's position limits"), "{e}");
    assert_eq!(json(&ok(&b, &["table", "list", "--json"]))["active"], 1);

    ok(&b, &["param", "save"]);
    let before = json(&ok(&b, &["param", "list", "--json"]));
    drop(b);

    // Restart `serve` on the same flash file: exactly the same settings, table 1, and
    // the board says it booted the last save.
    let b = serve(&flash);
    let after = json(&ok(&b, &["param", "list", "--json"]));
    assert_eq!(after, before);
    let st = json(&ok(&b, &["status", "--json"]));
    assert_eq!(st["active_id"], 1);
    assert_eq!(st["boot_reason"], "newest");
    assert!(st["boot_slot"].is_number());
    let text = ok(&b, &["status"]);
    assert!(text.contains(": the last save"), "{text}");
}
