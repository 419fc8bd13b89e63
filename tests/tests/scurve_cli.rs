//! End to end: `host-sim scurve` writes the CSV the issue specifies, from the
//! controller's own fixed-point S-curve (SPEC §B).

use host_sim::cmd::scurve::{plan_to_csv, Args};

fn args(from: Option<Vec<f64>>, to: Vec<f64>, v: f64, a: f64, j: f64, t: f64) -> Args {
    Args {
        to,
        from,
        vmax: v,
        amax: a,
        jerk: j,
        period: t,
        csv: std::path::PathBuf::new(),
        json: true,
    }
}

/// Parses the CSV: header and rows.
fn read(path: &std::path::Path) -> (String, Vec<Vec<f64>>, Vec<String>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let raw: Vec<String> = lines.map(str::to_string).collect();
    let rows = raw
        .iter()
        .map(|l| l.split(',').map(|x| x.parse::<f64>().unwrap()).collect())
        .collect();
    (header, rows, raw)
}

#[test]
fn three_axis_line_csv() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("line.csv");
    let a = args(
        Some(vec![10.0, -20.0, 5.0]),
        vec![130.0, 40.5, -15.25],
        200.0,
        1000.0,
        20_000.0,
        0.002,
    );
    let r = plan_to_csv(&a, &csv).unwrap();
    let (header, rows, raw) = read(&csv);
    assert_eq!(header, "t,pos,vel,acc,axis0,axis1,axis2");
    assert_eq!(rows.len() as u64, r.samples);
    // 17 significant digits in every field.
    for field in raw[1].split(',') {
        let mantissa = field.split('e').next().unwrap().trim_start_matches('-');
        assert_eq!(
            mantissa.chars().filter(char::is_ascii_digit).count(),
            17,
            "{field}"
        );
    }
    // t = k·T from 0; the first row is the start, the last the target, exactly.
    assert_eq!(rows[0][0], 0.0);
    assert_eq!(&rows[0][4..], &[10.0, -20.0, 5.0]);
    let last = rows.last().unwrap();
    assert_eq!(&last[4..], &[130.0, 40.5, -15.25]);
    assert_eq!(r.final_mm, vec![130.0, 40.5, -15.25]);
    assert!((last[1] - r.path_length).abs() < 1e-12);
    // Time-optimal within one period.
    assert!(r.time_error >= 0.0 && r.time_error < 0.002);
    assert!((last[0] - r.last_sample_time).abs() < 1e-12);
    // Path limits (mm/s, mm/s²) respected, position non-decreasing along the path.
    let d = [120.0, 60.5, -20.25];
    let lsb_mm = 1.0 / 256_000.0;
    for w in rows.windows(2) {
        assert!(w[1][1] >= w[0][1]);
        assert!(w[1][2] <= 200.0 + 1e-9 && w[1][3].abs() <= 1000.0 + 1e-9);
        // Every axis on the line through the leader (axis 0): ½ LSB.
        let s = (w[1][4] - 10.0) / d[0];
        for i in 1..3 {
            let on_line = [10.0, -20.0, 5.0][i] + d[i] * s;
            assert!((w[1][4 + i] - on_line).abs() <= 0.5 * lsb_mm + 1e-12);
        }
    }
    assert_eq!(r.phase_durations.len(), 7);
    let json = serde_json::to_value(&r).unwrap();
    for key in ["duration", "phase_durations", "final", "samples"] {
        assert!(json.get(key).is_some(), "{key}");
    }
}

#[test]
fn bad_input_names_the_argument() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("x.csv");
    let e = plan_to_csv(&args(None, vec![1.0], 1.0, 0.0, 1.0, 0.01), &csv).unwrap_err();
    assert!(e.to_string().starts_with("--amax"), "{e}");
    let e = plan_to_csv(
        &args(Some(vec![0.0]), vec![1.0, 2.0], 1.0, 1.0, 1.0, 0.01),
        &csv,
    )
    .unwrap_err();
    assert!(e.to_string().starts_with("--from"), "{e}");
}
