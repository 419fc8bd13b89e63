//! The spool-less fit's tests: its kernels and spool model, malformed recordings, and
//! the recovery of an off-nominal machine from quantised, noisy, skewed readings.

use super::*;

mod parts {
    use super::*;

    #[test]
    fn the_kernels_pass_their_polynomials_exactly() {
        let sig = 2.5;
        let x: Vec<f64> = (0..200)
            .map(|i| 3.0 + 0.5 * f64::from(i) + 0.01 * f64::from(i * i))
            .collect();
        let (h0, h1, h2) = (kernel(0, sig), kernel(1, sig), kernel(2, sig));
        let i = 100usize;
        let f = |h: &[f64]| filter(h, &x)[i].unwrap();
        let t = i as f64;
        // A parabola's smoothing adds σ²·x''/2 (a Gaussian's second moment).
        assert!((f(&h0) - (3.0 + 0.5 * t + 0.01 * t * t + 0.01 * sig * sig)).abs() < 1e-3);
        assert!((f(&h1) - (0.5 + 0.02 * t)).abs() < 1e-9);
        assert!((f(&h2) - 0.02).abs() < 1e-9);
        // No constant leaks into a derivative (a position of 0.1 m read every 1 ms).
        assert!(h1.iter().sum::<f64>().abs() < 1e-15);
        assert!(h2.iter().sum::<f64>().abs() * 0.1 / 1e-6 < 1e-6);
        assert_eq!(filter(&h0, &x)[0], None);
    }

    #[test]
    fn a_malformed_recording_is_an_error_not_a_panic() {
        let s = crate::scenario::Scenario::default();
        let known = s.axes[0].plant(s.supply(), 0.25);
        let r = Recording {
            period_s: 0.0,
            u: vec![0.0; 100],
            x_m: vec![0.25; 100],
            pa_pa: vec![80e5; 100],
            pb_pa: vec![80e5; 100],
            driven: Vec::new(),
        };
        assert!(matches!(
            identify_spoolless(&known, std::slice::from_ref(&r), 0.0),
            Err(IdentifyError::Unphysical {
                name: "period_s",
                ..
            })
        ));
        let short = Recording {
            period_s: 1e-3,
            x_m: vec![0.25; 99],
            ..r.clone()
        };
        assert!(identify_spoolless(&known, &[short], 0.0).is_err());
        let still = Recording {
            period_s: 1e-3,
            ..r
        };
        assert!(
            identify_spoolless(&known, &[still], 0.0).is_err(),
            "nothing excited"
        );
        assert!(
            identify_spoolless(&known, &[], 0.0).is_err(),
            "no recording"
        );
    }

    #[test]
    fn the_modelled_spool_is_a_delayed_second_order_lag() {
        let mut u = vec![0.0; 10];
        u.extend(vec![0.5; 490]);
        let w = std::f64::consts::TAU * 60.0;
        let s = spool(&u, 1e-3, w, 0.8, SUB);
        assert_eq!(s[11], 0.0, "one tick of delay");
        assert!(s[12] > 0.0);
        assert!((s[499] - 0.5).abs() < 1e-6);
        // The overshoot of ζ 0.8: exp(−πζ/√(1−ζ²)) = 1.5 %.
        let peak = s.iter().cloned().fold(0.0, f64::max);
        assert!((peak / 0.5 - 1.015).abs() < 0.003, "{peak}");
    }
}

mod recovery {
    use super::*;
    use crate::cmd::open_loop::simulate;
    use crate::identify::tests::off_nominal;
    use crate::scenario::Scenario;

    /// The open-loop excitation of the parent's tests on `truth`, read through 1 µm
    /// counts and a 12-bit 250 bar ADC (plus Gaussian noise of `noise_bar` on each
    /// pressure), the command quantised by the 12-bit DAC.
    fn recording(truth: &Scenario, noise_bar: f64, seed: u64) -> Recording {
        skewed_recording(truth, noise_bar, seed, 0)
    }

    /// [`recording`] with the pressures sampled `skew` tenths of a tick after (> 0) or
    /// before (< 0) the position.
    fn skewed_recording(truth: &Scenario, noise_bar: f64, seed: u64, skew: i64) -> Recording {
        let cmd = crate::identify::tests::excitation();
        let a = &truth.axes[0];
        let mut plant = a.plant(truth.supply(), 0.25);
        let fine = simulate(&mut plant, &cmd, truth.step_s(), 1e-4);
        let at = |k: usize| fine[(k as i64 * 10 + skew).clamp(0, fine.len() as i64 - 1) as usize];
        let out: Vec<_> = (0..fine.len().div_ceil(10))
            .map(|k| (at(k), fine[k * 10]))
            .collect();
        let u_at = |t: f64| {
            cmd.iter()
                .take_while(|(tc, _)| *tc <= t + 1e-9)
                .last()
                .map_or(0.0, |c| c.1)
        };
        let adc = crate::plant::sensors::PressureAdc {
            full_scale_pa: 250e5,
            bits: 12,
        };
        // A small LCG and Box–Muller: reproducible noise without a dependency.
        let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
        let mut uniform = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut gauss = move || {
            let (a, b) = (uniform(), uniform());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let mut r = Recording {
            period_s: 1e-3,
            ..Default::default()
        };
        for (p, s) in &out {
            // The command of the tick (held), quantised by the DAC.
            r.u.push((u_at(s.t) * 2047.0).round() / 2047.0);
            r.x_m.push((s.x_mm * 1e3).round() * 1e-6);
            r.pa_pa
                .push(adc.read_pa(p.pa_bar * 1e5 + noise_bar * 1e5 * gauss()));
            r.pb_pa
                .push(adc.read_pa(p.pb_bar * 1e5 + noise_bar * 1e5 * gauss()));
        }
        r
    }

    #[test]
    fn a_given_pressure_skew_is_taken_out_of_the_force_balance() {
        let truth = off_nominal();
        let t = &truth.axes[0];
        let nominal = Scenario::default();
        let known = nominal.axes[0].plant(nominal.supply(), 0.25);
        // Pressures sampled 0.3 ms before the position.
        let rec = skewed_recording(&truth, 0.0, 7, -3);
        let visc = |skew_s: f64| {
            let id = identify_spoolless(&known, std::slice::from_ref(&rec), skew_s).unwrap();
            id.get("viscous_n_s_per_m").unwrap().value / t.cylinder.viscous_n_s_per_m - 1.0
        };
        let (ignored, taken) = (visc(0.0), visc(-0.3e-3));
        let wrong_way = visc(0.3e-3);
        println!(
            "viscous with a 0.3 ms skew: ignored {:+.1} %, taken out {:+.1} %, doubled {:+.1} %",
            100.0 * ignored,
            100.0 * taken,
            100.0 * wrong_way
        );
        assert!(taken.abs() < 0.05, "{taken}");
        assert!(taken.abs() < ignored.abs() && ignored.abs() < wrong_way.abs());
    }

    #[test]
    fn quantised_and_noisy_readings_recover_the_machine() {
        let truth = off_nominal();
        let t = &truth.axes[0];
        let nominal = Scenario::default();
        let known = nominal.axes[0].plant(nominal.supply(), 0.25);
        for noise in [0.0, 0.5] {
            let rec = recording(&truth, noise, 7);
            let id = identify_spoolless(&known, &[rec], 0.0).unwrap();
            for (name, truth) in [
                ("mass_kg", t.cylinder.mass_kg),
                ("bulk_modulus_pa", t.cylinder.bulk_modulus_pa),
                ("rated_flow_extend_l_per_min", t.valve.rated_flow_l_per_min),
                ("rated_flow_retract_l_per_min", t.valve.rated_flow_l_per_min),
                ("viscous_n_s_per_m", t.cylinder.viscous_n_s_per_m),
                ("coulomb_n", t.cylinder.coulomb_n),
            ] {
                let p = id.get(name).unwrap();
                let err = p.value / truth - 1.0;
                println!(
                    "noise {noise} bar: {name} {:.4e} ± {:.2e} (true {truth:.4e}, {:+.2} %)",
                    p.value,
                    p.std,
                    100.0 * err
                );
                // Measured: within 5 % (docs/results.md, "Identification and
                // tuning"); the criterion is 10 %.
                assert!(
                    err.abs() < 0.10,
                    "noise {noise} bar: {name} {:+.1} %",
                    100.0 * err
                );
                assert!(p.std.is_finite() && p.std >= 0.0);
            }
            // The valve's low-frequency lag 2ζ/ω + delay (the command is applied at once).
            let lag = 2.0 * t.valve.damping / (std::f64::consts::TAU * t.valve.bandwidth_hz) * 1e3;
            let fit = id.get("valve_lag_ms").unwrap().value;
            println!("noise {noise} bar: valve lag {fit:.3} ms (true {lag:.3} ms)");
            assert!(
                (fit / lag - 1.0).abs() < 0.10,
                "lag {fit} ms, true {lag} ms"
            );
        }
    }
}
