use super::*;
use proptest::prelude::*;
use std::vec::Vec;

fn um(x: f64) -> i32 {
    (x * 256.0).round() as i32
}

/// Runs `e(t)` (µm, t in s) for `n` ticks of 1 ms, from a reset history (the first
/// tick's change is 0, as the position law gives it); returns the ticks it backed off on.
fn run(c: &BackoffCoeffs, st: &mut BackoffState, n: usize, e: impl Fn(f64) -> f64) -> Vec<usize> {
    let mut prev = None;
    (0..n)
        .filter(|&k| {
            let ek = um(e(k as f64 * 1e-3));
            let de = prev.map_or(0, |p: i32| ek.saturating_sub(p));
            prev = Some(ek);
            observe(c, st, de)
        })
        .collect()
}

#[test]
fn off_at_zero_and_refuses_a_bad_band() {
    assert_eq!(
        BackoffCoeffs::build(0.0, &BackoffSettings::DEFAULT, 1000),
        Ok(BackoffCoeffs::OFF)
    );
    assert!(!BackoffCoeffs::OFF.is_on());
    for bad in [-1.0, f32::NAN, f32::INFINITY, 10_001.0] {
        assert_eq!(
            BackoffCoeffs::build(bad, &BackoffSettings::DEFAULT, 1000),
            Err(BandError::Range),
            "{bad}"
        );
    }
    let c = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    assert!(c.is_on());
    assert_eq!(
        (c.band, c.window_ticks, c.settle_ticks, c.decay_shift),
        (1024, 150, 100, 9)
    );
    // A 1 s period: the windows are one tick each, never zero; the band decays at once.
    let slow = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1_000_000).unwrap();
    assert_eq!(
        (slow.window_ticks, slow.settle_ticks, slow.decay_shift),
        (1, 1, 0)
    );
}

/// A 25 Hz oscillation growing from 1 µm (the soft corner's signature): caught on its
/// fourth half-cycle beyond ±4 µm; while it keeps growing (this test signal ignores the
/// gain) it takes the next level at the end of each 100 ms settling — it rose in the
/// settling's second half — never deeper than the last; the scales are 0.36 and then
/// 0.75× each.
#[test]
fn a_growing_oscillation_backs_off_level_by_level() {
    let c = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    let mut st = BackoffState::RESET;
    let grow = |t: f64| (1.0 + 10.0 * t).powi(2) * (2.0 * core::f64::consts::PI * 25.0 * t).sin();
    let hits = run(&c, &mut st, 4000, grow);
    assert_eq!(hits.len(), usize::from(MAX_LEVEL), "{hits:?}");
    assert_eq!(st.level(), MAX_LEVEL);
    // The first: the high-passed amplitude (×0.93 at 25 Hz) passes 4 µm at 0.11 s; the
    // first excursion sets the side, the next four half-cycles of 20 ms count.
    let first = hits[0];
    assert!((110..=230).contains(&first), "{first}");
    // Each next one as the 100 ms of settling end: it still grows.
    for w in hits.windows(2) {
        assert_eq!(w[1] - w[0], 100, "{hits:?}");
    }
    let mut lv = BackoffState::RESET;
    let full = lv.scale(1 << 20);
    let c = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    assert_eq!(full, 1 << 20);
    let want = [1.0, 0.36, 0.27, 0.2025, 0.1519];
    for w in want {
        let s = f64::from(lv.scale(1 << 20)) / f64::from(full);
        assert!((s - w).abs() < 1e-3, "level {}: {s} vs {w}", lv.level);
        // The integrator: kept while the PI corner rises ≤ 1/0.36, then min(1, s/0.36).
        let si = f64::from(lv.scale_i(1 << 20)) / f64::from(full);
        let wi = (w / 0.36).min(1.0);
        assert!(
            (si - wi).abs() < 2e-3,
            "level {}: Ki {si} vs {wi}",
            lv.level
        );
        lv.peak = 0;
        cut(&c, &mut lv);
    }
}

/// The oscillation the backoff cured: after the cut (0.202 s, as in the test above) it
/// carries on 20 % higher for a cycle — the valve and the oil column — and dies away
/// (here 25 Hz with a time constant of 0.1 or 0.3 s; one decaying slower than the band's
/// 0.5 s takes the next level when the band falls below it). The raised band keeps it
/// from taking the gain any further, and a carry-over inside the settling's first half
/// is not growth.
#[test]
fn a_decaying_oscillation_after_a_backoff_takes_no_further_level() {
    let c = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    let w = 2.0 * core::f64::consts::PI * 25.0;
    let shape = |t: f64, tau: f64| {
        let a = if t < 0.202 {
            (1.0 + 10.0 * t).powi(2)
        } else if t < 0.242 {
            9.8 * (1.0 + 5.0 * (t - 0.202))
        } else {
            11.76 * (-(t - 0.242) / tau).exp()
        };
        a * (w * t).sin()
    };
    for tau in [0.1, 0.3] {
        let mut st = BackoffState::RESET;
        let hits = run(&c, &mut st, 3000, |t| shape(t, tau));
        assert_eq!(hits, [202], "τ {tau} s");
        assert_eq!(st.level(), 1);
    }
    // The same oscillation still rising through the settling grows at this gain: the
    // next level as the settling ends.
    let mut st = BackoffState::RESET;
    let late = |t: f64| {
        let a = if t < 0.302 {
            (1.0 + 10.0 * t).powi(2)
        } else {
            16.3 * (-(t - 0.302) / 0.1).exp()
        };
        a * (w * t).sin()
    };
    let hits = run(&c, &mut st, 3000, late);
    assert_eq!(hits, [202, 302]);
    // A tracking transient in the settling's second half — one-sided, 3× the
    // oscillation's peak — is not growth.
    let mut st = BackoffState::RESET;
    let swing = |t: f64| {
        let bump = if t > 0.26 {
            30.0 * (1.0 - (-(t - 0.26) / 0.01).exp())
        } else {
            0.0
        };
        shape(t, 0.1) + bump
    };
    let hits = run(&c, &mut st, 3000, swing);
    assert_eq!(hits, [202]);
    // Nor is a jump of 60 µm that decays within 20 … 40 ms (the 10 Hz high-pass
    // overshoots it to the other side, smaller than the jump).
    for tau in [0.02, 0.03, 0.04] {
        let mut st = BackoffState::RESET;
        let jump = |t: f64| {
            let j = if t > 0.26 {
                60.0 * (-(t - 0.26) / tau).exp()
            } else {
                0.0
            };
            shape(t, 0.1) + j
        };
        let hits = run(&c, &mut st, 3000, jump);
        assert_eq!(hits, [202], "τ {tau} s");
    }
}

/// An oscillation whose settling after the first cut happened to see a beat (the
/// second half small: no growth there) and that then grows again at the new gain by
/// 15 % a cycle: the growth watch takes the next level on the third same-side
/// half-cycle beyond ±4 µm after the first whole one, each 1/16 above the last (0.58 s);
/// without the watch it took no level by 0.6 s (measured: it must first outgrow the
/// raised band, 1.25 × 9 µm decaying with τ = 0.5 s, four times). A steady oscillation
/// after the
/// settling (peaks within 1/16) takes no level from the watch.
#[test]
fn an_oscillation_growing_after_the_settling_takes_the_next_level_early() {
    let c = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    let w = 2.0 * core::f64::consts::PI * 25.0;
    let shape = |t: f64, grow: bool| {
        let a = if t < 0.202 {
            (1.0 + 10.0 * t).powi(2)
        } else if t < 0.252 {
            9.8
        } else if t < 0.302 {
            2.0
        } else if grow {
            3.0 * ((t - 0.302) / 0.286).exp()
        } else {
            6.0
        };
        a * (w * t).sin()
    };
    let mut st = BackoffState::RESET;
    let hits = run(&c, &mut st, 600, |t| shape(t, true));
    assert_eq!(hits.len(), 2, "{hits:?}");
    assert_eq!(hits[0], 202);
    assert!((550..600).contains(&hits[1]), "{hits:?}");
    let mut st = BackoffState::RESET;
    let hits = run(&c, &mut st, 700, |t| shape(t, false));
    assert_eq!(hits, [202]);
}

/// Two tones beating are not growth: after the first cut a 25 Hz mode decays from
/// 9.84 µm with τ = 1 s under a 1 µm ripple at 30 Hz (its peaks on
/// one side rise for half of each 200 ms beat, 7.15 → 7.67 → 8.28 µm). The watch takes
/// no level; the count takes the next one only when the raised band (τ = 0.5 s) has
/// fallen below the slower-decaying mode, after 0.8 s.
#[test]
fn a_beating_decay_after_a_cut_takes_no_level_from_the_watch() {
    let c = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    let pi2 = 2.0 * core::f64::consts::PI;
    let e = |t: f64| {
        if t < 0.202 {
            (1.0 + 10.0 * t).powi(2) * (pi2 * 25.0 * t).sin()
        } else {
            9.84 * (-(t - 0.202) / 1.0).exp() * (pi2 * 25.0 * t).sin() + (pi2 * 30.0 * t).sin()
        }
    };
    let mut st = BackoffState::RESET;
    let hits = run(&c, &mut st, 1200, e);
    assert_eq!(hits.first(), Some(&202), "{hits:?}");
    assert!(hits.iter().skip(1).all(|&k| k > 800), "{hits:?}");
}

/// What a following axis shows when nothing oscillates: a table corner's slow swing of
/// 50 µm, a 1 Hz tracking ripple of ±20 µm, the slave encoder's ±1 µm count jitter and a
/// single sharp step of 30 µm (a load bump). None backs off.
#[test]
fn tracking_errors_and_noise_do_not_back_off() {
    let c = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    let cases: [(&str, &dyn Fn(f64) -> f64); 4] = [
        ("corner", &|t: f64| 50.0 * (1.0 - (-t / 0.05).exp())),
        ("ripple", &|t: f64| {
            20.0 * (2.0 * core::f64::consts::PI * t).sin()
        }),
        ("jitter", &|t: f64| {
            if (t * 1e3).round() as i64 % 2 == 0 {
                1.0
            } else {
                -1.0
            }
        }),
        ("bump", &|t: f64| {
            if t > 0.5 {
                30.0 * (-(t - 0.5) / 0.02).exp()
            } else {
                0.0
            }
        }),
    ];
    for (name, e) in cases {
        let mut st = BackoffState::RESET;
        assert_eq!(run(&c, &mut st, 5000, e), Vec::<usize>::new(), "{name}");
        assert_eq!(st.level(), 0, "{name}");
    }
}

/// Off: never backs off whatever the error does. A restart (a run's start, a cleared
/// fault) forgets the history but keeps the level.
#[test]
fn off_never_acts_and_a_restart_keeps_the_level() {
    let mut st = BackoffState::RESET;
    let osc = |t: f64| 100.0 * (2.0 * core::f64::consts::PI * 25.0 * t).sin();
    let off = BackoffCoeffs::build(0.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    // The law never runs the detector when it is off; called anyway it must not act.
    assert_eq!(run(&off, &mut st, 1000, osc), Vec::<usize>::new());
    assert_eq!(st.level(), 0);
    let c = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    let mut st = BackoffState::RESET;
    assert_eq!(run(&c, &mut st, 100, osc).len(), 1);
    st.restart();
    assert_eq!(st.level(), 1);
    assert_eq!(st.scale_q16(), 23_593);
    assert_eq!((st.y, st.half_cycles, st.settle, st.env), (0, 0, 0, 0));
}

proptest! {
    #[test]
    fn never_panics_and_the_level_stays_in_range(
        seq in proptest::collection::vec(any::<i32>(), 1..400),
        band in 0.0f32..10_000.0, period in 50u32..1_000_000)
    {
        let c = BackoffCoeffs::build(band, &BackoffSettings::DEFAULT, period).unwrap();
        let mut st = BackoffState::RESET;
        for de in seq {
            observe(&c, &mut st, de);
            prop_assert!(st.level() <= MAX_LEVEL);
            let s = st.scale(i32::MAX);
            prop_assert!(s > 0);
        }
    }
}

/// The defaults give the scales, margin and growth of the module's description.
#[test]
fn the_default_settings_are_the_described_detector() {
    let c = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    assert_eq!(c.scale_q16, [65_536, 23_593, 17_695, 13_271, 9_953]);
    assert_eq!(c.ki_scale_q16, [65_536, 65_536, 49_152, 36_864, 27_648]);
    assert_eq!((c.margin_q16, c.growth_q16), (16_384, 4_096));
    assert_eq!(
        (c.half_cycles, c.max_level, c.growth_half_cycles),
        (4, MAX_LEVEL, 3)
    );
}

/// Every threshold out of its range is refused by name, also with the band off (a
/// setting is refused when written); an integer threshold refuses a fraction.
#[test]
fn a_bad_threshold_is_refused_by_name() {
    for (f, lo, hi, integer) in BackoffSettings::RANGES {
        let mut bad = [lo - 1.0, hi * 2.0 + 1.0, f32::NAN, f32::INFINITY].to_vec();
        if integer {
            bad.push(lo + 0.5);
        }
        for v in bad {
            let mut s = BackoffSettings::DEFAULT;
            *s.get_mut(f) = v;
            for band in [0.0, 4.0] {
                assert_eq!(
                    BackoffCoeffs::build(band, &s, 1000),
                    Err(BandError::Setting(f)),
                    "{f:?} = {v}, band {band}"
                );
            }
        }
        let mut s = BackoffSettings::DEFAULT;
        for v in [lo, hi] {
            *s.get_mut(f) = v;
            assert!(BackoffCoeffs::build(4.0, &s, 1000).is_ok(), "{f:?} = {v}");
        }
    }
}

/// The thresholds act: a shallower deepest level stops the cuts there, and more
/// half-cycles per oscillation see the growing one later.
#[test]
fn the_thresholds_change_what_the_detector_does() {
    let grow = |t: f64| (1.0 + 10.0 * t).powi(2) * (2.0 * core::f64::consts::PI * 25.0 * t).sin();
    let default = BackoffCoeffs::build(4.0, &BackoffSettings::DEFAULT, 1000).unwrap();
    let first = run(&default, &mut BackoffState::default(), 4000, grow)[0];
    let shallow = BackoffSettings {
        max_level: 2.0,
        ..BackoffSettings::DEFAULT
    };
    let c = BackoffCoeffs::build(4.0, &shallow, 1000).unwrap();
    let mut st = BackoffState::RESET;
    assert_eq!(run(&c, &mut st, 4000, grow).len(), 2);
    assert_eq!((st.level(), st.scale_q16()), (2, 17_695));
    let patient = BackoffSettings {
        half_cycles: 8.0,
        window_ms: 300.0,
        ..BackoffSettings::DEFAULT
    };
    let c = BackoffCoeffs::build(4.0, &patient, 1000).unwrap();
    let later = run(&c, &mut BackoffState::default(), 4000, grow)[0];
    // Four more half-cycles of a 25 Hz oscillation: 80 ms.
    assert!((later - first).abs_diff(80) <= 5, "{first} → {later}");
}
