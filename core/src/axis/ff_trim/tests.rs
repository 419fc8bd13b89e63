use super::*;

const LSB: i32 = 65_536;

#[test]
fn off_at_zero_and_refuses_a_bad_tau() {
    assert_eq!(FfTrimCoeffs::build(0.0, 1000, 2047), Ok(FfTrimCoeffs::OFF));
    assert!(!FfTrimCoeffs::OFF.is_on());
    for bad in [-1.0, f32::NAN, f32::INFINITY, 0.005, 1000.5] {
        assert_eq!(
            FfTrimCoeffs::build(bad, 1000, 2047),
            Err(FfTrimError::Range),
            "{bad}"
        );
    }
    // Shorter than 16 periods.
    assert_eq!(
        FfTrimCoeffs::build(0.015, 1000, 2047),
        Err(FfTrimError::Range)
    );
    let c = FfTrimCoeffs::build(1.0, 1000, 2047).unwrap();
    assert!(c.is_on());
    // 1 000 ticks → n = 10; ff_ref 2^9 LSB = 2^25 raw; ff_min 2 047/64 LSB.
    assert_eq!((c.shift, c.ff_min, c.ff_max), (35, 2047 << 10, 2047 << 16));
}

/// The loop's view: whatever the trimmed feed-forward misses, the integrator holds
/// (here at once). A valve 27 % faster than calibrated needs 1/1.27 of the
/// feed-forward; after 5 τ·ff_ref/|ff| the trim holds it within 1 % and the
/// integrator nearly nothing, and the command never jumps on the way.
#[test]
fn learns_the_valve_ratio_per_direction_without_a_bump() {
    let c = FfTrimCoeffs::build(0.5, 1000, 2047).unwrap();
    let mut st = FfTrimState::RESET;
    for (ff_lsb, ratio) in [(400, 1.0 / 1.27), (-300, 1.2)] {
        let ff = ff_lsb * LSB;
        let need = (f64::from(ff) * ratio) as i32;
        let mut integ = need - st.apply(ff);
        for _ in 0..5000 {
            let before = st.apply(ff) + integ;
            integ -= st.offload(&c, ff, integ);
            let after = st.apply(ff) + integ;
            assert!((before - after).abs() <= 2, "bump {before} → {after}");
            // The loop re-balances what rounding left.
            integ = need - st.apply(ff);
        }
        let r = f64::from(st.ratio_q16(ff > 0)) / 65_536.0;
        assert!((r - ratio).abs() < 0.01 * ratio, "{ff_lsb}: {r} vs {ratio}");
        assert!(integ.abs() < LSB, "{ff_lsb}: integrator {integ}");
    }
    // Each direction kept its own.
    let neg = f64::from(st.ratio_q16(false)) / 65_536.0;
    let pos = f64::from(st.ratio_q16(true)) / 65_536.0;
    assert!((pos - 1.0 / 1.27).abs() < 0.01 && (neg - 1.2).abs() < 0.015);
}

/// At rest (below 1/64 of the clamp) and beyond the clamp nothing moves: a null offset
/// held at rest stays in the integrator. Beyond the clamp (ratio 0.5 … 2) the rest stays in the integrator.
#[test]
fn nothing_moves_at_rest_and_the_ratio_is_clamped() {
    let c = FfTrimCoeffs::build(0.02, 1000, 2047).unwrap();
    let mut st = FfTrimState::RESET;
    for ff in [0, 31 * LSB, -31 * LSB, 2048 * LSB, -2048 * LSB, i32::MIN] {
        assert_eq!(st.offload(&c, ff, 50 * LSB), 0);
    }
    assert_eq!(st, FfTrimState::RESET);
    let ff = 100 * LSB;
    let mut integ = 500 * LSB;
    for _ in 0..10_000 {
        integ -= st.offload(&c, ff, integ);
    }
    assert_eq!(st.ratio_q16(true), 2 * 65_536);
    assert!((integ - 400 * LSB).abs() < LSB, "{integ}");
    let mut integ = -500 * LSB;
    for _ in 0..10_000 {
        integ -= st.offload(&c, ff, integ);
    }
    assert_eq!(st.ratio_q16(true), 65_536 / 2);
}

proptest::proptest! {
    /// Never panics; the ratios stay within 0.5 … 2; the command ff' + I is kept within
    /// rounding whatever the values.
    #[test]
    fn never_panics_and_keeps_the_command(
        tau in 0.016f32..100.0,
        clamp in 1u16..=2047,
        steps in proptest::collection::vec((proptest::num::i32::ANY, -(1i32 << 27)..(1 << 27)), 1..50),
    ) {
        let c = FfTrimCoeffs::build(tau, 1000, clamp).unwrap();
        let mut st = FfTrimState::RESET;
        for (ff, integ) in steps {
            let before = i64::from(st.apply(ff)) + i64::from(integ);
            let took = st.offload(&c, ff, integ);
            let after = i64::from(st.apply(ff)) + i64::from(integ) - i64::from(took);
            for p in [false, true] {
                let r = st.ratio_q16(p);
                proptest::prop_assert!((32_768..=131_072).contains(&r));
            }
            // ff' saturates at ±2^31 for the largest ff; within it, no bump.
            if st.apply(ff).unsigned_abs() < (1 << 30) {
                proptest::prop_assert!((before - after).abs() <= 2, "{before} → {after}");
            }
        }
    }
}
