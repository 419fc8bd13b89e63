//! The identification test move: a slave excited around where it holds, under the law's
//! own position control, while the loop-rate capture records its valve command,
//! position and pressures (`host-sim motion test`, then `host-sim identify`).
//!
//! The excitation is a **position reference** `r(t) = c + A·f(t)` about the held
//! position `c` — closed loop, so the slave stays within `c ± A` (plus the law's
//! overshoot) and inside the axis' limits, whatever the machine; what the fit needs is
//! the valve command the law gives and the axis' answer to it, both recorded. Profiles:
//!
//! - **step**: `f` = +1, 0, −1, 0, … each held `dwell` (a square wave through the
//!   centre: both directions, from rest, at the law's own acceleration);
//! - **prbs**: `f = ±1` from a 9-bit maximum-length sequence (x⁹ + x⁵ + 1, period 511
//!   bits) of one bit per `dwell` — a broadband excitation;
//! - **chirp**: `f = sin φ`, `φ̇ = 2π·f(t)`, the frequency swept linearly from `f₀` to
//!   `f₁` over the test; velocity and acceleration feed-forward `A·φ̇·cos φ` and
//!   `A·(φ̈·cos φ − φ̇²·sin φ)`.
//!
//! After `duration` the reference returns to `c` (a step of at most `A`; a chirp's
//! velocity feed-forward steps from up to `A·2π·f₁` to 0) and holds.
//!
//! **Refused before anything moves**: a step of the reference — `A` for step and chirp
//! (whose end, or a Hold, steps back to the centre by up to `A`), `2A` for PRBS (−A →
//! +A) — not below the axis' following-error limit `e_max` (the step would trip it); `c ± (A + e_max)` outside the axis' limits (the reference stays within
//! `c ± A`, and the axis cannot get further than `e_max` beyond it without the
//! following-error fault: valves at null); a chirp whose peak speed `A·2π·max(f₀, f₁)`
//! is above the axis' top speed. The default 1.8 s PRBS with 20 ms bits uses 90 of the
//! sequence's 511 bits: a pseudo-random square wave, not the full maximum-length
//! spectrum.
//!
//! Fixed point: the phase is a `u32` fraction of a turn (2⁻³² turn), its increment per
//! tick `f·T·2³²` (≤ 2³²/10: `f ≤ 1/(10T)`); sine and cosine in `f32` (the M4's FPU;
//! ≈ 1e-7 relative, 0.03 µm at the largest amplitude), positions `I24F8` µm.

use crate::axis::PosRef;
use crate::units::{AccUmPerS2, PosUm, VelUmPerS};

/// Largest amplitude, µm (100 mm).
pub const TEST_AMPLITUDE_MAX_UM: u32 = 100_000;
/// Longest test, ms.
pub const TEST_DURATION_MAX_MS: u32 = 60_000;

/// The shape of a test move.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TestProfile {
    /// +A, 0, −A, 0, … each held `dwell`.
    Step,
    /// A linear frequency sweep `f₀ → f₁`.
    Chirp,
    /// ±A from a 9-bit maximum-length sequence, one bit per `dwell`.
    Prbs,
}

impl TestProfile {
    /// Wire code: 0 step, 1 chirp, 2 prbs.
    pub const fn code(self) -> u8 {
        match self {
            TestProfile::Step => 0,
            TestProfile::Chirp => 1,
            TestProfile::Prbs => 2,
        }
    }

    /// The profile of a wire code.
    pub const fn from_code(c: u8) -> Option<Self> {
        match c {
            0 => Some(TestProfile::Step),
            1 => Some(TestProfile::Chirp),
            2 => Some(TestProfile::Prbs),
            _ => None,
        }
    }
}

/// A test move as commanded (integers in the units of their names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TestSpec {
    /// The shape.
    pub profile: TestProfile,
    /// Amplitude `A`, µm (1 … [`TEST_AMPLITUDE_MAX_UM`]).
    pub amplitude_um: u32,
    /// Duration, ms (1 … [`TEST_DURATION_MAX_MS`], at least one period).
    pub duration_ms: u32,
    /// Step and PRBS: how long each level holds, ms (≥ one period).
    pub dwell_ms: u32,
    /// Chirp: start frequency, mHz.
    pub f_start_mhz: u32,
    /// Chirp: end frequency, mHz (both ≤ 1/(10T)).
    pub f_end_mhz: u32,
}

/// Why a test move cannot run (before anything moves).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TestError {
    /// Amplitude 0 or above [`TEST_AMPLITUDE_MAX_UM`], duration or dwell shorter than a
    /// period or too long, a chirp frequency above 1/(10T).
    Spec,
    /// `c ± (A + e_max)` leaves the axis' limits.
    OutsideLimits,
    /// A step of the reference (`A`, PRBS `2A`) is not below the following-error limit.
    Step,
    /// The chirp's peak speed `A·2π·max(f₀, f₁)` is above the axis' top speed.
    TooFast,
}

/// A running test move (one slave).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TestMove {
    profile: TestProfile,
    center: PosUm,
    amplitude: PosUm,
    /// Ticks done, and the test's length in ticks.
    k: u32,
    n: u32,
    /// Step / PRBS: ticks per level.
    dwell: u32,
    /// PRBS shift register (9 bits, never 0).
    lfsr: u16,
    /// Step / PRBS: the present level, −1 … 1.
    level: i8,
    /// Chirp: phase, 2⁻³² turn; increment per tick at the start and at the end.
    phase: u32,
    dphase0: u32,
    dphase1: u32,
    /// Chirp, made once: the amplitude, µm; rad/s per phase increment per tick
    /// (`2π / (2³²·T)`); the sweep's constant φ̈, rad/s².
    amp_um: f32,
    rad_s_per_dphase: f32,
    wdot: f32,
}

/// One turn of the chirp's phase, 2³² (as `f32`).
const TURN: f32 = 4_294_967_296.0;

/// `x · num / den` in u64, saturating (0 for den = 0).
fn mul_div_u(x: u64, num: u64, den: u64) -> u64 {
    x.saturating_mul(num).checked_div(den).unwrap_or(0)
}

impl TestMove {
    /// Plans a test about `center` at `period_us`, within `range` (min, max), the top
    /// speed `max_speed_um_per_s` and the following-error limit `max_error` (module
    /// docs).
    pub fn new(
        spec: &TestSpec,
        center: PosUm,
        range: (PosUm, PosUm),
        max_speed_um_per_s: u32,
        max_error: PosUm,
        period_us: u32,
    ) -> Result<Self, TestError> {
        let period_us64 = u64::from(period_us.max(1));
        let ticks = |ms: u32| mul_div_u(u64::from(ms), 1000, period_us64);
        let n = ticks(spec.duration_ms);
        let dwell = ticks(spec.dwell_ms);
        let per_level = matches!(spec.profile, TestProfile::Step | TestProfile::Prbs);
        if spec.amplitude_um == 0
            || spec.amplitude_um > TEST_AMPLITUDE_MAX_UM
            || spec.duration_ms > TEST_DURATION_MAX_MS
            || n == 0
            || (per_level && (dwell == 0 || dwell > n))
        {
            return Err(TestError::Spec);
        }
        // f·T·2³² per tick, f in mHz: f_mHz · T_us · 2³² / 10⁹.
        let dphase = |mhz: u32| mul_div_u(u64::from(mhz), period_us64 << 32, 1_000_000_000);
        let limit = u64::from(u32::MAX / 10);
        let (d0, d1) = (dphase(spec.f_start_mhz), dphase(spec.f_end_mhz));
        if spec.profile == TestProfile::Chirp && (d0 > limit || d1 > limit || d1 == 0) {
            return Err(TestError::Spec);
        }
        let amp_bits = i32::try_from(spec.amplitude_um)
            .ok()
            .and_then(|a| a.checked_mul(256))
            .ok_or(TestError::Spec)?;
        let amplitude = PosUm::from_bits(amp_bits);
        let e_max = i64::from(max_error.to_bits()).saturating_abs();
        let (c, a) = (i64::from(center.to_bits()), i64::from(amp_bits));
        // A chirp steps back to its centre (by up to A) when it ends or is held.
        let step = match spec.profile {
            TestProfile::Step | TestProfile::Chirp => a,
            TestProfile::Prbs => a.saturating_mul(2),
        };
        if step >= e_max {
            return Err(TestError::Step);
        }
        let reach = a.saturating_add(e_max);
        let (lo, hi) = (c.saturating_sub(reach), c.saturating_add(reach));
        if lo < i64::from(range.0.to_bits()) || hi > i64::from(range.1.to_bits()) {
            return Err(TestError::OutsideLimits);
        }
        if spec.profile == TestProfile::Chirp {
            let peak = core::f32::consts::TAU
                * spec.amplitude_um as f32
                * (spec.f_start_mhz.max(spec.f_end_mhz) as f32 * 1e-3);
            if peak > max_speed_um_per_s as f32 {
                return Err(TestError::TooFast);
            }
        }
        let rad_s_per_dphase = core::f32::consts::TAU / TURN / (period_us.max(1) as f32 * 1e-6);
        let n32 = u32::try_from(n).map_err(|_| TestError::Spec)?;
        Ok(Self {
            profile: spec.profile,
            center,
            amplitude,
            k: 0,
            n: n32,
            dwell: u32::try_from(dwell).unwrap_or(u32::MAX),
            lfsr: 0x1FF,
            level: 0,
            phase: 0,
            dphase0: u32::try_from(d0).unwrap_or(0),
            dphase1: u32::try_from(d1).unwrap_or(0),
            amp_um: amplitude.to_num::<f32>(),
            rad_s_per_dphase,
            // (Δφ per tick changes by (d1 − d0)/n per tick: φ̈ = that / T in rad/s².)
            wdot: (d1 as f32 - d0 as f32) / n32.max(1) as f32 * rad_s_per_dphase
                / (period_us.max(1) as f32 * 1e-6),
        })
    }

    /// Where the test started and returns to.
    pub fn center(&self) -> PosUm {
        self.center
    }

    /// Shifts the test by `delta` (the slave was re-referenced: its measured position
    /// moved by `delta`).
    pub fn rebase(&mut self, delta: PosUm) {
        self.center = self.center.saturating_add(delta);
    }

    /// Whether the test has ended (the reference is back at the centre).
    pub fn done(&self) -> bool {
        self.k >= self.n
    }

    /// The next bit of the 9-bit maximum-length sequence (x⁹ + x⁵ + 1).
    fn prbs_bit(&mut self) -> bool {
        let bit = ((self.lfsr >> 8) ^ (self.lfsr >> 4)) & 1;
        self.lfsr = ((self.lfsr << 1) | bit) & 0x1FF;
        bit == 1
    }

    /// One tick: this tick's reference (the centre once done).
    pub fn step(&mut self) -> PosRef {
        if self.done() {
            return PosRef {
                x_ref_um: self.center,
                ..PosRef::default()
            };
        }
        let k = self.k;
        self.k = self.k.saturating_add(1);
        let (center, amplitude) = (self.center, self.amplitude);
        let at = |level: i8| PosRef {
            x_ref_um: match level {
                1 => center.saturating_add(amplitude),
                -1 => center.saturating_sub(amplitude),
                _ => center,
            },
            ..PosRef::default()
        };
        match self.profile {
            TestProfile::Step => {
                // +1, 0, −1, 0 by quarter: the level index is (k / dwell) mod 4.
                let q = k.checked_div(self.dwell).unwrap_or(0) % 4;
                self.level = match q {
                    0 => 1,
                    2 => -1,
                    _ => 0,
                };
                at(self.level)
            }
            TestProfile::Prbs => {
                if k.checked_rem(self.dwell).unwrap_or(0) == 0 {
                    self.level = if self.prbs_bit() { 1 } else { -1 };
                }
                at(self.level)
            }
            TestProfile::Chirp => self.chirp(k),
        }
    }

    /// The chirp's reference at tick `k` (module docs), advancing the phase.
    fn chirp(&mut self, k: u32) -> PosRef {
        // The increment of this tick: linear from dphase0 to dphase1 over the test.
        let (d0, d1) = (i64::from(self.dphase0), i64::from(self.dphase1));
        let d = d0.saturating_add(
            d1.saturating_sub(d0)
                .saturating_mul(i64::from(k))
                .checked_div(i64::from(self.n))
                .unwrap_or(0),
        );
        let angle = self.phase as f32 / TURN * core::f32::consts::TAU;
        let (s, c) = (libm::sinf(angle), libm::cosf(angle));
        // φ̇ (rad/s); φ̈ is constant.
        let w = d as f32 * self.rad_s_per_dphase;
        let (wdot, a_um) = (self.wdot, self.amp_um);
        self.phase = self.phase.wrapping_add(u32::try_from(d).unwrap_or(0));
        // I24F8 bits of a value in µm (a float-to-integer `as` saturates; NaN gives 0);
        // the acceleration is `I32F0`, whole µm/s².
        let q8 = |x: f32| (x * 256.0) as i32;
        PosRef {
            x_ref_um: self.center.saturating_add(PosUm::from_bits(q8(a_um * s))),
            v_ff_um_per_s: VelUmPerS::from_bits(q8(a_um * w * c)),
            a_ff_um_per_s2: AccUmPerS2::from_bits((a_um * (wdot * c - w * w * s)) as i32),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(profile: TestProfile) -> TestSpec {
        TestSpec {
            profile,
            amplitude_um: 1000,
            duration_ms: 2000,
            dwell_ms: 250,
            f_start_mhz: 1000,
            f_end_mhz: 20_000,
        }
    }

    fn um(x: i32) -> PosUm {
        PosUm::from_num(x)
    }

    const RANGE: (PosUm, PosUm) = (PosUm::ZERO, PosUm::from_bits(500_000 << 8));
    /// The following-error limit, 5 mm.
    const E: PosUm = PosUm::from_bits(5000 << 8);

    /// The references of `s` about 100 mm at 1 ms, to the first tick after its end.
    fn run(s: &TestSpec) -> std::vec::Vec<PosRef> {
        let mut t = TestMove::new(s, um(100_000), RANGE, 200_000, E, 1000).expect("valid");
        let mut out = std::vec::Vec::new();
        while !t.done() {
            out.push(t.step());
        }
        out.push(t.step());
        out
    }

    #[test]
    fn the_step_is_a_square_wave_through_the_centre_and_returns() {
        let r = run(&spec(TestProfile::Step));
        assert_eq!(r.len(), 2001);
        let x = |i: usize| r[i].x_ref_um.to_num::<i32>();
        assert_eq!((x(0), x(249)), (101_000, 101_000));
        assert_eq!((x(250), x(499)), (100_000, 100_000));
        assert_eq!((x(500), x(749)), (99_000, 99_000));
        assert_eq!((x(750), x(1000)), (100_000, 101_000));
        assert_eq!(x(2000), 100_000, "back at the centre");
    }

    #[test]
    fn the_prbs_is_balanced_and_changes_on_bit_boundaries_only() {
        let mut s = spec(TestProfile::Prbs);
        s.dwell_ms = 4;
        s.duration_ms = 511 * 4;
        let r = run(&s);
        let x: std::vec::Vec<i32> = r.iter().map(|p| p.x_ref_um.to_num::<i32>()).collect();
        for (i, w) in x[..511 * 4].windows(2).enumerate() {
            if (i + 1) % 4 != 0 {
                assert_eq!(w[0], w[1], "tick {i}");
            }
        }
        let high = x[..511 * 4].iter().filter(|&&v| v == 101_000).count();
        // A maximum-length sequence: 256 ones and 255 zeros per period.
        assert_eq!(high, 256 * 4);
        assert_eq!(
            x[..511 * 4].iter().filter(|&&v| v == 99_000).count(),
            255 * 4
        );
    }

    #[test]
    fn the_chirp_sweeps_with_consistent_feed_forward() {
        let r = run(&spec(TestProfile::Chirp));
        let x: std::vec::Vec<f64> = r.iter().map(|p| p.x_ref_um.to_num::<f64>()).collect();
        // The velocity feed-forward is the reference's derivative (central difference).
        for i in (1..1999).step_by(97) {
            let dx = (x[i + 1] - x[i - 1]) / 2e-3;
            let v = r[i].v_ff_um_per_s.to_num::<f64>();
            assert!(
                (dx - v).abs() < 0.02 * 1000.0 * 6.3 * 20.0,
                "tick {i}: {dx} vs {v}"
            );
        }
        // The acceleration feed-forward (whole µm/s²) is its second difference.
        for i in (1..1999).step_by(89) {
            let ddx = (x[i + 1] - 2.0 * x[i] + x[i - 1]) / 1e-6;
            let a = f64::from(r[i].a_ff_um_per_s2.to_bits());
            let peak = 1000.0 * (std::f64::consts::TAU * 20.0).powi(2);
            assert!((ddx - a).abs() < 0.02 * peak, "tick {i}: {ddx} vs {a}");
        }
        // The amplitude stays A, the frequency rises: zero crossings closer at the end.
        assert!(x.iter().all(|v| (v - 100_000.0).abs() <= 1000.01));
        let crossings = |a: usize, b: usize| {
            x[a..b]
                .windows(2)
                .filter(|w| (w[0] - 100_000.0).signum() != (w[1] - 100_000.0).signum())
                .count()
        };
        assert!(crossings(1500, 2000) > 3 * crossings(0, 500));
        assert_eq!(x[2000], 100_000.0);
    }

    #[test]
    fn impossible_tests_are_refused_before_anything_moves() {
        let ok = |s: &TestSpec, c: i32| TestMove::new(s, um(c), RANGE, 200_000, E, 1000);
        let mut s = spec(TestProfile::Step);
        s.amplitude_um = 0;
        assert_eq!(ok(&s, 1000), Err(TestError::Spec));
        s.amplitude_um = TEST_AMPLITUDE_MAX_UM + 1;
        assert_eq!(ok(&s, 250_000), Err(TestError::Spec));
        let mut s = spec(TestProfile::Step);
        s.dwell_ms = 0;
        assert_eq!(ok(&s, 100_000), Err(TestError::Spec));
        s.dwell_ms = 3000;
        assert_eq!(
            ok(&s, 100_000),
            Err(TestError::Spec),
            "dwell longer than the test"
        );
        let s = spec(TestProfile::Step);
        assert_eq!(ok(&s, 500), Err(TestError::OutsideLimits));
        assert_eq!(ok(&s, 499_500), Err(TestError::OutsideLimits));
        // c − A − e_max: 5 999 µm leaves 0 by 1 µm, 6 000 does not.
        assert_eq!(ok(&s, 5999), Err(TestError::OutsideLimits));
        assert!(ok(&s, 6000).is_ok());
        // A step of A (PRBS 2A) must stay below the following-error limit of 5 mm.
        let mut s = spec(TestProfile::Step);
        s.amplitude_um = 5000;
        assert_eq!(ok(&s, 100_000), Err(TestError::Step));
        let mut s = spec(TestProfile::Prbs);
        s.amplitude_um = 2500;
        assert_eq!(ok(&s, 100_000), Err(TestError::Step));
        s.amplitude_um = 2499;
        assert!(ok(&s, 100_000).is_ok());
        let mut s = spec(TestProfile::Chirp);
        s.f_end_mhz = 5000;
        s.amplitude_um = 5000;
        assert_eq!(
            ok(&s, 100_000),
            Err(TestError::Step),
            "its end steps back by A"
        );
        s.amplitude_um = 4999;
        assert!(ok(&s, 100_000).is_ok());
        let mut s = spec(TestProfile::Chirp);
        s.f_end_mhz = 101_000; // above 1/(10T) at 1 ms
        assert_eq!(ok(&s, 100_000), Err(TestError::Spec));
        s.f_end_mhz = 40_000; // 1 mm · 2π · 40 Hz = 251 mm/s > 200 mm/s
        assert_eq!(ok(&s, 100_000), Err(TestError::TooFast));
        let mut s = spec(TestProfile::Chirp);
        s.duration_ms = TEST_DURATION_MAX_MS + 1;
        assert_eq!(ok(&s, 100_000), Err(TestError::Spec));
        s.duration_ms = 0;
        assert_eq!(ok(&s, 100_000), Err(TestError::Spec));
    }
}
