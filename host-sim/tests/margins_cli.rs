//! `host-sim margins`: the shipped feed-forward set's loop measured on the reference
//! machine by the valve probe, as JSON; a wrong axis or an oscillating machine refused
//! naming what is wrong.

use std::process::{Command, Output};

fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .expect("host-sim runs")
}

#[test]
fn margins_of_the_shipped_set_and_refusals() {
    let o = host_sim(&["margins", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let m = &v["margins"];
    assert_eq!(m["axis"], "tangent");
    assert_eq!(v["period_us"], 1000);
    let points = m["points"].as_array().expect("points");
    assert_eq!(points.len(), host_sim::margins::POINTS);
    let gm = m["gain_margin_db"].as_f64().expect("gain margin");
    let pm = m["phase_margin_deg"].as_f64().expect("phase margin");
    let fc = m["gain_crossover_hz"].as_f64().expect("crossover");
    println!("shipped 1 ms set: GM {gm:.1} dB, PM {pm:.1}° at {fc:.1} Hz");
    assert!(
        (3.0..9.0).contains(&gm) && (35.0..70.0).contains(&pm),
        "{m}"
    );
    assert!((5.0..30.0).contains(&fc), "{fc}");

    let o = host_sim(&["margins", "--axis", "side_press"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("no follower axis `side_press`"),
        "{e}"
    );
}
