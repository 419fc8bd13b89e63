//! `host-sim contour-estimate`: the JSON object's shape and the benchmark targets
//! (docs/contour.md) at the default settings (deterministic: seeded points, fixed-point core).

use host_sim::cmd::contour_estimate::{evaluate, Args, PathKind};

#[test]
fn json_shape_is_the_documented_one() {
    let (rep, _) = evaluate(&Args::default()).unwrap();
    let v = serde_json::to_value(&rep).unwrap();
    let obj = v.as_object().unwrap();
    let mut keys: Vec<&str> = obj.keys().map(String::as_str).collect();
    keys.sort_unstable();
    assert_eq!(keys, ["feed_mm_s", "methods", "path"]);
    assert_eq!(v["path"], "parabola");
    assert_eq!(v["feed_mm_s"], 200.0);
    let methods = v["methods"].as_object().unwrap();
    let mut names: Vec<&str> = methods.keys().map(String::as_str).collect();
    names.sort_unstable();
    assert_eq!(names, ["adaptive", "chord", "tangent"]);
    for m in methods.values() {
        let m = m.as_object().unwrap();
        assert_eq!(m.len(), 2);
        assert!(m["max_abs_error_um"].as_f64().unwrap() >= 0.0);
        assert!(m["rms_error_um"].as_f64().unwrap() >= 0.0);
    }
}

/// Defaults (parabola, 200 mm/s, 1 ms, K = 10, E = 50 µm, Q = 1 s): adaptive max error
/// ≤ 0.1 µm, ≥ 10× below the chord method, ≥ 100× below the tangent method. Measured:
/// 0.0125 µm, 40×, 15 600×.
#[test]
fn default_benchmark_meets_the_targets() {
    let (rep, det) = evaluate(&Args::default()).unwrap();
    let m = rep.methods;
    let a = m.adaptive.max_abs_error_um;
    assert!(a <= 0.1, "adaptive {a}");
    assert!(
        m.chord.max_abs_error_um >= 10.0 * a,
        "chord {}",
        m.chord.max_abs_error_um
    );
    assert!(
        m.tangent.max_abs_error_um >= 100.0 * a,
        "tangent {}",
        m.tangent.max_abs_error_um
    );
    assert!(det.samples > 1000);
    assert!(
        a <= det.bound_um,
        "adaptive {a} above its a-priori bound {}",
        det.bound_um
    );
}

#[test]
fn bad_arguments_are_rejected_with_a_message() {
    let bad = |f: &dyn Fn(&mut Args)| {
        let mut a = Args::default();
        f(&mut a);
        evaluate(&a).unwrap_err().to_string()
    };
    assert!(bad(&|a| a.feed = 0.0).contains("--feed"));
    assert!(bad(&|a| a.lag_periods = 100).contains("--lag-periods"));
    assert!(bad(&|a| a.period_us = 1).contains("--period-us"));
    assert!(bad(&|a| a.h_max = 1000).contains("--h-max"));
    assert!(bad(&|a| a.offset_um = -1.0).contains("--offset-um"));
    let mut a = Args {
        path: PathKind::Line,
        ..Args::default()
    };
    a.lag_periods = 3;
    assert!(evaluate(&a).is_ok());
}
