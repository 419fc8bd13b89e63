//! A pressure-controlled axis: position approach, then force control with a bumpless
//! switch (the side press of the stretch-bending machine, SPEC §A).
//!
//! ```text
//! F = A_A·p_A − A_B·p_B                                   N (from the two transducers)
//! Approach: x_ref += v_app·T toward x_end;  u = Kp·(x_ref − x) + kv·v_app
//! Switch when F ≥ F_contact (once the approach has run t_arm):
//!                             F_ref := F,  I_F := u(k−1)   (so u is continuous)
//! Force:  F_ref → F_set at F_set/t_ramp;  e_F = F_ref − F
//!         I_F = clamp(I_F + Ki_F·T·e_F, ±clamp) (not further into saturation)
//!         u = Kp_F·e_F + I_F
//! ```
//!
//! Formats: pressure `I16F16` bar, force `I24F8` N, chamber force gain A/10 N/bar
//! `I16F16` (A in mm²), force gains `I8F24` LSB/N and LSB/(N·tick).

use crate::fixed_point::{clamp_sym, mul_shr_floor_sat};
use crate::units::{CmdLsb, DacCode, ForceN, PosUm, PressureBar, VelUmPerS};
use crate::valve::{ValveCal, ValveCalError, ValveCoeffs};
use fixed::types::{I16F16, I8F24};

/// The press law's gains: what a tuning produces for one force axis at one control
/// period. With the `serde` feature it is what a scenario's `[tuning.press.<name>]` table
/// holds (every field optional, defaults as below; unknown keys refused).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(deny_unknown_fields, default)
)]
pub struct PressGains {
    /// Position gain during the approach, LSB/µm (0 … 1000).
    pub kp_lsb_per_um: f32,
    /// Velocity feed-forward during the approach, LSB/(µm/s) (0 … 100).
    pub kv_lsb_per_um_s: f32,
    /// Force proportional gain, LSB/N (0 … 100).
    pub kp_lsb_per_n: f32,
    /// Force integral gain, LSB/(N·s) (0 … 1e4).
    pub ki_lsb_per_n_s: f32,
}

impl Default for PressGains {
    fn default() -> Self {
        Self {
            kp_lsb_per_um: 0.2,
            kv_lsb_per_um_s: 0.0,
            kp_lsb_per_n: 0.005,
            ki_lsb_per_n_s: 0.1,
        }
    }
}

/// Press axis configuration in engineering units.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PressConfig {
    /// Piston-side area A_A, mm² (1 … 100 000).
    pub area_a_mm2: f32,
    /// Rod-side area A_B, mm² (1 … 100 000).
    pub area_b_mm2: f32,
    /// End of the approach ramp (beyond the expected contact), µm.
    pub approach_end_um: f32,
    /// Approach speed, µm/s (> 0, ≤ 1e6).
    pub approach_speed_um_per_s: f32,
    /// Force at which contact is declared and force control takes over, N (> 0).
    pub contact_force_n: f32,
    /// Time from the start of the approach before contact can be declared, ms
    /// (0 … 60 000): the force that accelerates the piston at the start of the approach
    /// must not be taken for the work.
    pub contact_arm_ms: f32,
    /// Force set-point, N (> 0, ≤ 1e6).
    pub force_set_n: f32,
    /// Time to ramp the force reference from contact to the set-point, ms (1 … 60 000).
    pub force_ramp_ms: f32,
    /// Gains of the approach and of the force loop.
    pub gains: PressGains,
    /// Valve output calibration.
    pub valve: ValveCal,
}

/// A press parameter out of range (the field it names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PressConfigError {
    /// An area.
    Area,
    /// `approach_end_um`.
    ApproachEnd,
    /// `approach_speed_um_per_s`.
    ApproachSpeed,
    /// `kp_lsb_per_um` or `kv_lsb_per_um_s`.
    PositionGain,
    /// `contact_force_n` or `contact_arm_ms`.
    ContactForce,
    /// `force_set_n`.
    ForceSet,
    /// `force_ramp_ms`.
    ForceRamp,
    /// `kp_lsb_per_n` or `ki_lsb_per_n_s`.
    ForceGain,
    /// The control period.
    Period,
    /// The valve calibration.
    Valve(ValveCalError),
}

/// Validated press coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PressCoeffs {
    ka: i32,        // N/bar I16F16
    kb: i32,        // N/bar I16F16
    x_end: i32,     // µm I24F8
    step_um: i32,   // µm per tick I24F8
    v_app: i32,     // µm/s I24F8
    kp: i32,        // I16F16
    kv: i32,        // I8F24
    f_contact: i32, // N I24F8
    arm_ticks: u32, // ticks of approach before contact detection
    f_set: i32,     // N I24F8
    f_step: i32,    // N per tick I24F8
    kp_f: i32,      // I8F24
    ki_f: i32,      // I8F24 per tick
    valve: ValveCoeffs,
}

fn chk(x: f32, lo: f32, hi: f32, e: PressConfigError) -> Result<f64, PressConfigError> {
    if x.is_finite() && x >= lo && x <= hi {
        Ok(f64::from(x))
    } else {
        Err(e)
    }
}

fn bits<F: fixed::traits::Fixed<Bits = i32>>(
    x: f64,
    e: PressConfigError,
) -> Result<i32, PressConfigError> {
    F::checked_from_num(x).map(F::to_bits).ok_or(e)
}

/// `x` N as [`ForceN`] raw bits, or `e` if out of range.
fn force_bits(x: f64, e: PressConfigError) -> Result<i32, PressConfigError> {
    ForceN::checked_from_num(x).map(ForceN::to_bits).ok_or(e)
}

impl PressConfig {
    /// Validates the configuration for a control period and converts it.
    pub fn build(&self, period_us: u32) -> Result<PressCoeffs, PressConfigError> {
        use PressConfigError as E;
        if !(50..=1_000_000).contains(&period_us) {
            return Err(E::Period);
        }
        let t = f64::from(period_us) * 1e-6;
        let aa = chk(self.area_a_mm2, 1.0, 1e5, E::Area)?;
        let ab = chk(self.area_b_mm2, 1.0, 1e5, E::Area)?;
        let x_end = chk(self.approach_end_um, -8e6, 8e6, E::ApproachEnd)?;
        let v = chk(self.approach_speed_um_per_s, 1e-3, 1e6, E::ApproachSpeed)?;
        let kp = chk(self.gains.kp_lsb_per_um, 0.0, 1000.0, E::PositionGain)?;
        let kv = chk(self.gains.kv_lsb_per_um_s, 0.0, 100.0, E::PositionGain)?;
        let fc = chk(self.contact_force_n, 1e-3, 1e6, E::ContactForce)?;
        let fs = chk(self.force_set_n, 1e-3, 1e6, E::ForceSet)?;
        let ramp = chk(self.force_ramp_ms, 1.0, 60_000.0, E::ForceRamp)?;
        let arm = chk(self.contact_arm_ms, 0.0, 60_000.0, E::ContactForce)?;
        let kpf = chk(self.gains.kp_lsb_per_n, 0.0, 100.0, E::ForceGain)?;
        let kif = chk(self.gains.ki_lsb_per_n_s, 0.0, 1e4, E::ForceGain)?;
        Ok(PressCoeffs {
            ka: bits::<I16F16>(aa / 10.0, E::Area)?,
            kb: bits::<I16F16>(ab / 10.0, E::Area)?,
            x_end: bits::<fixed::types::I24F8>(x_end, E::ApproachEnd)?,
            step_um: bits::<fixed::types::I24F8>(v * t, E::ApproachSpeed)?,
            v_app: VelUmPerS::checked_from_num(v)
                .map(VelUmPerS::to_bits)
                .ok_or(E::ApproachSpeed)?,
            kp: bits::<I16F16>(kp, E::PositionGain)?,
            kv: bits::<I8F24>(kv, E::PositionGain)?,
            f_contact: force_bits(fc, E::ContactForce)?,
            arm_ticks: (arm * 1e-3 / t) as u32,
            f_set: force_bits(fs, E::ForceSet)?,
            f_step: force_bits(fs * t / (ramp * 1e-3), E::ForceRamp)?.max(1),
            kp_f: bits::<I8F24>(kpf, E::ForceGain)?,
            ki_f: bits::<I8F24>(kif * t, E::ForceGain)?,
            valve: self.valve.build().map_err(E::Valve)?,
        })
    }
}

/// Which loop is closed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PressPhase {
    /// Position control toward the work.
    #[default]
    Approach,
    /// Force control.
    Force,
}

/// Press axis state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PressState {
    /// Current phase.
    pub phase: PressPhase,
    x_ref: i32,
    started: bool,
    approach_ticks: u32,
    f_ref: i32,
    integ: i32,
    u_last: i32,
}

/// One tick's result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PressOutput {
    /// Valve code.
    pub dac: DacCode,
    /// Command before the output stage, LSB.
    pub cmd_lsb: CmdLsb,
    /// Measured force, N.
    pub force_n: ForceN,
    /// Force reference (0 during the approach), N.
    pub force_ref_n: ForceN,
    /// Phase after this tick.
    pub phase: PressPhase,
}

/// F = A_A·p_A − A_B·p_B in N.
#[inline]
pub fn cylinder_force(c: &PressCoeffs, pa: PressureBar, pb: PressureBar) -> ForceN {
    // Q16·Q16 = Q32 → >> 24 = Q8.
    ForceN::from_bits(
        mul_shr_floor_sat(pa.to_bits(), c.ka, 24).saturating_sub(mul_shr_floor_sat(
            pb.to_bits(),
            c.kb,
            24,
        )),
    )
}

impl PressCoeffs {
    /// The code that puts the press valve's spool at its null.
    pub fn null_code(&self) -> DacCode {
        self.valve.null_code()
    }
}

impl PressState {
    /// The approach's position error x_ref − `x`, µm, while it approaches (0 under force
    /// control and before the first tick).
    pub fn approach_error_um(&self, x: PosUm) -> PosUm {
        if self.phase == PressPhase::Approach && self.started {
            PosUm::from_bits(self.x_ref.saturating_sub(x.to_bits()))
        } else {
            PosUm::ZERO
        }
    }

    /// One control tick.
    pub fn tick(
        &mut self,
        c: &PressCoeffs,
        x: PosUm,
        pa: PressureBar,
        pb: PressureBar,
    ) -> PressOutput {
        let f = cylinder_force(c, pa, pb).to_bits();
        let clamp = c.valve.clamp_lsb().to_bits();
        if !self.started {
            self.started = true;
            self.x_ref = x.to_bits();
        }
        let armed = self.approach_ticks >= c.arm_ticks;
        self.approach_ticks = self.approach_ticks.saturating_add(1);
        if self.phase == PressPhase::Approach && armed && f >= c.f_contact {
            self.phase = PressPhase::Force;
            self.f_ref = f;
            // Bumpless: e_F = 0 at the switch, so u = I_F = u(k−1).
            self.integ = self.u_last;
        }
        let u = match self.phase {
            PressPhase::Approach => {
                let dir = if c.x_end >= self.x_ref {
                    c.step_um
                } else {
                    c.step_um.wrapping_neg()
                };
                let next = self.x_ref.saturating_add(dir);
                self.x_ref = if (dir >= 0 && next > c.x_end) || (dir < 0 && next < c.x_end) {
                    c.x_end
                } else {
                    next
                };
                let moving = self.x_ref != c.x_end;
                let v = if !moving {
                    0
                } else if dir >= 0 {
                    c.v_app
                } else {
                    c.v_app.wrapping_neg()
                };
                let e = self.x_ref.saturating_sub(x.to_bits());
                mul_shr_floor_sat(e, c.kp, 8).saturating_add(mul_shr_floor_sat(v, c.kv, 16))
            }
            PressPhase::Force => {
                let (lo, hi) = if c.f_set >= self.f_ref {
                    (self.f_ref, c.f_set)
                } else {
                    (c.f_set, self.f_ref)
                };
                let stepped = if c.f_set >= self.f_ref {
                    self.f_ref.saturating_add(c.f_step)
                } else {
                    self.f_ref.saturating_sub(c.f_step)
                };
                self.f_ref = stepped.clamp(lo, hi);
                let e = self.f_ref.saturating_sub(f);
                let p = mul_shr_floor_sat(e, c.kp_f, 16);
                let cand = clamp_sym(
                    self.integ.saturating_add(mul_shr_floor_sat(e, c.ki_f, 16)),
                    clamp,
                );
                let u_try = p.saturating_add(cand);
                let winding = (u_try > clamp && cand > self.integ)
                    || (u_try < clamp.wrapping_neg() && cand < self.integ);
                if !winding {
                    self.integ = cand;
                }
                p.saturating_add(self.integ)
            }
        };
        let u = clamp_sym(u, clamp);
        self.u_last = u;
        let cmd = CmdLsb::from_bits(u);
        PressOutput {
            dac: c.valve.output(cmd),
            cmd_lsb: cmd,
            force_n: ForceN::from_bits(f),
            force_ref_n: ForceN::from_bits(if self.phase == PressPhase::Force {
                self.f_ref
            } else {
                0
            }),
            phase: self.phase,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cfg() -> PressConfig {
        PressConfig {
            area_a_mm2: 5026.5,
            area_b_mm2: 3436.1,
            approach_end_um: 60_000.0,
            approach_speed_um_per_s: 20_000.0,
            contact_force_n: 1000.0,
            contact_arm_ms: 0.0,
            force_set_n: 20_000.0,
            force_ramp_ms: 1000.0,
            gains: PressGains {
                kp_lsb_per_um: 0.2,
                kv_lsb_per_um_s: 0.017,
                kp_lsb_per_n: 0.01,
                ki_lsb_per_n_s: 0.5,
            },
            valve: ValveCal::default(),
        }
    }

    #[test]
    fn force_from_pressures() {
        let c = cfg().build(1000).unwrap();
        let f = cylinder_force(&c, PressureBar::from_num(100), PressureBar::from_num(50));
        // 100 bar · 502.65 N/bar − 50 · 343.61 = 33084.5 N
        assert!((f.to_num::<f64>() - 33_084.5).abs() < 0.1, "{f}");
    }

    #[test]
    fn switch_is_bumpless() {
        let c = cfg().build(1000).unwrap();
        let mut st = PressState::default();
        let mut last = None;
        // approach with no force, then force appears above the contact threshold
        for k in 0..200 {
            let x = PosUm::from_num(k as f64 * 19.0);
            let pa = if k < 150 {
                PressureBar::from_num(7)
            } else {
                PressureBar::from_num(12)
            };
            let o = st.tick(&c, x, pa, PressureBar::from_num(10));
            if k == 150 {
                assert_eq!(o.phase, PressPhase::Force);
                let prev: PressOutput = last.unwrap();
                assert_eq!(prev.phase, PressPhase::Approach);
                // the command moves only by one integral step (e_F = 0 at the switch)
                assert!((o.cmd_lsb - prev.cmd_lsb).saturating_abs() < CmdLsb::from_num(0.5));
            }
            last = Some(o);
        }
    }

    #[test]
    fn contact_is_not_declared_before_the_arm_time() {
        let mut cfg = cfg();
        cfg.contact_arm_ms = 50.0;
        let c = cfg.build(1000).unwrap();
        let mut st = PressState::default();
        // a large force from the start (the acceleration transient): ignored for 50 ticks
        for k in 0..60 {
            let o = st.tick(
                &c,
                PosUm::ZERO,
                PressureBar::from_num(50),
                PressureBar::ZERO,
            );
            assert_eq!(o.phase == PressPhase::Force, k >= 50, "tick {k}");
        }
    }

    #[test]
    fn rejects_bad_values() {
        let mut c = cfg();
        c.force_ramp_ms = 0.0;
        assert_eq!(c.build(1000), Err(PressConfigError::ForceRamp));
        let mut c = cfg();
        c.area_b_mm2 = -1.0;
        assert_eq!(c.build(1000), Err(PressConfigError::Area));
    }

    proptest! {
        #[test]
        fn output_in_range(seq in proptest::collection::vec((any::<i32>(), any::<i32>(), any::<i32>()), 1..100)) {
            let c = cfg().build(1000).unwrap();
            let mut st = PressState::default();
            for (x, a, b) in seq {
                let o = st.tick(&c, PosUm::from_bits(x), PressureBar::from_bits(a), PressureBar::from_bits(b));
                prop_assert!(o.dac.get().abs() <= 2047);
            }
        }
    }
}
