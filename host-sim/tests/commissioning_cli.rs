//! Commissioning from the command line, against `host-sim serve --pty` run as a user
//! runs it (every step a `host-sim` process): status before and after a table, the
//! loop-rate capture around a command and around a fault (one CSV row per tick, the
//! trigger at t = 0), the fault's value and limit in status and its history, status
//! --watch, and nonsense refused with words.

mod common;
use common::{json, ok, refused, serve};

/// The CSV's rows as maps from column name to text.
fn csv_rows(path: &std::path::Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(path).expect("the capture CSV");
    let header: Vec<String> = r
        .headers()
        .expect("header")
        .iter()
        .map(String::from)
        .collect();
    assert_eq!(header[0], "t_s", "t_s is the first column");
    r.records()
        .map(|rec| {
            let rec = rec.expect("a row");
            header
                .iter()
                .cloned()
                .zip(rec.iter().map(String::from))
                .collect()
        })
        .collect()
}

fn num(row: &std::collections::HashMap<String, String>, col: &str) -> f64 {
    row[col]
        .parse()
        .unwrap_or_else(|_| panic!("{col}: {:?}", row[col]))
}

#[test]
fn status_capture_around_a_command_and_a_fault() {
    let dir = tempfile::tempdir().expect("tempdir");
    let s = serve(&dir.path().join("flash.bin"));

    // A fresh board: nothing to act on yet, in words and in JSON.
    let st = json(&ok(&s, &["status", "--json"]));
    assert_eq!(st["state"], "idle");
    assert_eq!(st["fault_code"], 0);
    assert!(st["fault_name"].is_null());
    assert_eq!(st["faults"].as_array().map(Vec::len), Some(0));
    assert_eq!(st["inputs"]["estop"], false);
    assert_eq!(st["inputs"]["valve_power"], false);
    assert_eq!(st["axes"][0]["reference"], "unreferenced");
    assert!(st["link"]["frames"].as_u64() > Some(0));
    let text = ok(&s, &["status"]);
    for want in [
        "E-stop released, valve power off",
        "no fault since boot",
        "unreferenced",
        "link",
    ] {
        assert!(text.contains(want), "{want:?} in\n{text}");
    }

    // A table, its rows and CRC in status; both slaves referenced where they are.
    let table = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/tangent_board.csv");
    let up = common::cli(&s, &["upload", table, "--activate", "--id", "42"]);
    assert!(up.status.success());
    let up = String::from_utf8_lossy(&up.stderr).to_string();
    let st = json(&ok(&s, &["status", "--json"]));
    assert_eq!(st["active_id"], 42);
    let rows = std::fs::read_to_string(table)
        .expect("table")
        .lines()
        .count()
        - 1;
    assert_eq!(st["active_rows"].as_u64(), Some(rows as u64));
    let crc = st["active_crc"].as_str().expect("crc").to_string();
    assert_eq!(crc.len(), 8);
    assert!(
        up.contains(&format!("CRC-32 {crc}")),
        "upload said {up:?}, status {crc}"
    );
    common::reference_where_they_are(&s);

    // Armed, then Start from another process: the capture freezes around the command.
    ok(
        &s,
        &[
            "capture",
            "--arm-only",
            "--trigger",
            "command",
            "--pre-ms",
            "100",
            "--post-ms",
            "300",
        ],
    );
    // More than the 100 ms before the trigger pass before it (sooner keeps fewer).
    std::thread::sleep(std::time::Duration::from_millis(300));
    ok(&s, &["motion", "start"]);
    let csv1 = dir.path().join("start.csv");
    let svg = dir.path().join("start.svg");
    let c1 = csv1.to_str().expect("utf-8");
    ok(
        &s,
        &[
            "capture",
            "--read-only",
            "--csv",
            c1,
            "--plot",
            svg.to_str().expect("utf-8"),
        ],
    );
    let r = csv_rows(&csv1);
    assert_eq!(r.len(), 401, "100 + 1 + 300 ticks");
    assert_eq!(num(&r[0], "t_s"), -0.1);
    assert_eq!(num(&r[100], "t_s"), 0.0);
    assert_eq!(
        r[100]["command"], "1",
        "the trigger row applied the command"
    );
    assert_eq!(r[100]["state"], "following");
    assert_eq!(
        (r[99]["state"].as_str(), r[99]["valve_power"].as_str()),
        ("idle", "0")
    );
    assert!(r[101..]
        .iter()
        .all(|x| x["state"] == "following" && x["valve_power"] == "1"));
    for w in r.windows(2) {
        assert_eq!(num(&w[1], "tick") - num(&w[0], "tick"), 1.0, "every tick");
    }
    for row in &r {
        let e = num(row, "target0_mm") - num(row, "actual0_mm") - num(row, "error0_mm");
        assert!(e.abs() < 2e-6, "error = target − actual");
        assert!(num(row, "pa0_bar") > 0.0, "chamber pressure recorded");
    }
    let plot = std::fs::read_to_string(&svg).expect("svg");
    for legend in ["target 0", "actual 0", "error 0", "dac 1", "p_B 0"] {
        assert!(plot.contains(legend), "legend {legend:?}");
    }

    // A 1 µm following-error limit trips the fault within the run; the capture's
    // trigger row is the first in Fault, and status names the value and the limit.
    ok(&s, &["motion", "stop"]);
    ok(&s, &["param", "set", "axis/0/following_error_um", "1"]);
    ok(
        &s,
        &[
            "capture",
            "--arm-only",
            "--trigger",
            "fault",
            "--pre-ms",
            "500",
            "--post-ms",
            "1500",
        ],
    );
    ok(&s, &["motion", "start"]);
    let csv2 = dir.path().join("fault.csv");
    ok(
        &s,
        &[
            "capture",
            "--read-only",
            "--timeout-s",
            "20",
            "--csv",
            csv2.to_str().expect("utf-8"),
        ],
    );
    let r = csv_rows(&csv2);
    let at = r
        .iter()
        .position(|x| num(x, "t_s") == 0.0)
        .expect("a trigger row");
    assert_eq!(r[at]["state"], "fault");
    // (The Start tick itself may trip it: 1 µm is below the error of the first tick.)
    assert_ne!(
        r[at - 1]["state"],
        "fault",
        "the trigger is the edge into Fault"
    );
    assert_eq!(r[at + 1]["valve_power"], "0", "valves off after the fault");
    let st = json(&ok(&s, &["status", "--json"]));
    assert_eq!(st["state"], "fault");
    assert_eq!(st["fault_name"], "following_error");
    assert_eq!(st["fault_axis"], 0);
    assert_eq!(st["fault_unit"], "mm");
    let (v, l) = (
        st["fault_value"].as_f64().expect("value"),
        st["fault_limit"].as_f64().expect("limit"),
    );
    assert!((l - 0.001).abs() < 1e-6, "limit {l} mm");
    assert!(v.abs() > l, "value {v} mm beyond the limit");
    let last = st["faults"]
        .as_array()
        .and_then(|f| f.last())
        .expect("history")
        .clone();
    assert_eq!(last["name"], "following_error");
    assert_eq!(
        last["tick"].as_u64().map(|t| t as f64),
        Some(num(&r[at], "tick"))
    );
    let text = ok(&s, &["status"]);
    assert!(
        text.contains("following_error on axis 0:") && text.contains("(limit 0.001 mm)"),
        "{text}"
    );

    // --watch: one JSON object per refresh.
    let w = ok(
        &s,
        &[
            "status",
            "--watch",
            "--json",
            "--count",
            "3",
            "--interval-ms",
            "50",
        ],
    );
    let lines: Vec<_> = w.lines().collect();
    assert_eq!(lines.len(), 3);
    assert!(lines.iter().all(|l| json(l)["state"] == "fault"));

    // The virtual master: rewound and run again at 50× without restarting `serve`; its
    // end is reported.
    ok(&s, &["motion", "clear-fault"]);
    let m = ok(&s, &["motion", "master", "rewind"]);
    assert!(m.starts_with("master stopped, 0.000 s of"), "{m}");
    ok(&s, &["motion", "master", "start", "--speed-scale", "50"]);
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let m = ok(&s, &["motion", "master", "status"]);
    assert!(
        m.contains("speed ×50") && m.contains("at the end of its profile"),
        "{m}"
    );
    let e = refused(&s, &["motion", "master", "start", "--speed-scale", "500"]);
    assert!(e.contains("0.01 … 100"), "{e}");

    // Nonsense gets words, before anything is sent or from the board; nothing is written.
    let x = dir.path().join("x.csv");
    let x_csv = x.to_str().expect("utf-8");
    let e = refused(
        &s,
        &["capture", "--trigger", "threshold:speed0>1", "--csv", x_csv],
    );
    assert!(e.contains("speed0"), "{e}");
    let e = refused(
        &s,
        &[
            "capture",
            "--pre-ms",
            "2048",
            "--post-ms",
            "0",
            "--csv",
            x_csv,
        ],
    );
    assert!(
        e.contains("longer than the board's ring (2048 ticks"),
        "{e}"
    );
    let e = refused(&s, &["capture", "--pre-ms", "-5", "--csv", x_csv]);
    assert!(e.contains("≥ 0 ms"), "{e}");
    assert!(!x.exists(), "a refused capture writes no file");
}
