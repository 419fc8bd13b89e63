//! The cross-coupled contour controller for an X–Y pair of axes (SPEC §D).
//!
//! ```text
//! u1 = law_x(x_V, x_P),  u2 = law_y(y_V, y_P)            (per-axis tracking laws)
//! ε  = −C1·E1 + C2·E2                                    ([`super::contour_model`])
//! u_c = law_c(ε)                                         (the contour law on ε)
//! U1 = u1 + u_ff1 − C1·u_c,   U2 = u2 + u_ff2 + C2·u_c   [DAC LSB, clamped to ±2047]
//! (u_ff: optional velocity feed-forward, [`CrossCoupled::set_feedforward`])
//! ```
//!
//! With ε > 0 when P is right of the direction of travel, `(−C1, C2) ≈ n` is the left
//! normal: a positive `u_c` pushes P back toward the path. The law is generic
//! ([`ErrorLaw`]): [`Pid`] gives Koren's classic CCC ([`Ccc`]), [`Npid`] the seed's
//! cross-coupled nonlinear PID ([`Cnp`]).
//!
//! Three ticks, all allocation-free and infallible:
//! * [`CrossCoupled::tick_independent`] — no coupling (`u_c = 0`); ε is still computed
//!   from the frame for monitoring.
//! * [`CrossCoupled::tick_model`] — ε and C1, C2 from the line/circle model at V.
//! * [`CrossCoupled::tick_estimated`] — ε is given (the seed-003 estimator's signed
//!   contour error, any path) and the correction is distributed along the path normal
//!   at the estimator's foot point (C1 = sin θ_f, C2 = cos θ_f: the model's curvature
//!   terms only serve to *estimate* ε, which is measured here).

use super::contour_model::{contour_model, PathFrame};
use super::npid::Npid;
use super::pid::Pid;
use super::{cmd_from_q16, q16_from_pos, ErrorLaw};
use hydra_core::fixed_point::mul64_shr_floor_sat;
use hydra_core::units::{CmdLsb, PosUm};

/// Largest |command| of an axis, LSB Q16 (the 12-bit DAC's ±2047).
const U_MAX_Q16: i64 = 2047 << 16;

/// Coefficients of the three laws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct XyCoeffs<C> {
    /// X-axis tracking law.
    pub x: C,
    /// Y-axis tracking law.
    pub y: C,
    /// Contour law (acts on ε).
    pub contour: C,
}

/// State of the three laws.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CrossCoupled<L> {
    /// X-axis law.
    pub x: L,
    /// Y-axis law.
    pub y: L,
    /// Contour law.
    pub contour: L,
    /// Feed-forward commands `[X, Y]` added to the axis laws' outputs, LSB (zero unless
    /// set by [`CrossCoupled::set_feedforward`] before a tick).
    feedforward_lsb: [CmdLsb; 2],
}

/// Classic cross-coupled controller (linear PIDs).
pub type Ccc = CrossCoupled<Pid>;
/// Cross-coupled nonlinear PID (TD + fal on the axes and on ε).
pub type Cnp = CrossCoupled<Npid>;

/// One tick's result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct XyOutput {
    /// Valve commands `[U1, U2]`, LSB (±2047).
    pub command: [CmdLsb; 2],
    /// The contour error used (model or estimate), µm; ε > 0 right of travel.
    pub contour_error_um: PosUm,
    /// The contour law's output u_c, LSB.
    pub contour_command: CmdLsb,
}

fn pos_from_q16(x: i64) -> PosUm {
    let raw = x
        .wrapping_shr(8)
        .clamp(i64::from(i32::MIN), i64::from(i32::MAX));
    PosUm::from_bits(raw as i32)
}

/// `u + g·u_c` (g Q30), clamped to ±2047 LSB.
fn distribute(u: CmdLsb, g_q30: i64, uc: CmdLsb) -> CmdLsb {
    let corr = mul64_shr_floor_sat(g_q30, i64::from(uc.to_bits()), 30);
    cmd_from_q16(
        i64::from(u.to_bits())
            .saturating_add(corr)
            .clamp(-U_MAX_Q16, U_MAX_Q16),
    )
}

/// [`distribute`] for a unit gain (`|g| ≤ 2³⁰`, Q30: sin/cos of the foot frame) on
/// 32-bit words: `|g·u_c| ≤ 2³⁰·2³¹`, shifted `|corr| ≤ 2³¹` only for |u_c| near the
/// `i32` limit (saturated), the sum a `qadd`, then the ±2047 LSB clamp. Same value as
/// [`distribute`].
#[inline(always)]
fn distribute_unit(u: CmdLsb, g_q30: i32, uc: CmdLsb) -> CmdLsb {
    let corr = hydra_core::fixed_point::mul_shr_floor_sat(g_q30, uc.to_bits(), 30);
    CmdLsb::from_bits(
        u.to_bits()
            .saturating_add(corr)
            .clamp((U_MAX_Q16 as i32).wrapping_neg(), U_MAX_Q16 as i32),
    )
}

impl<L: ErrorLaw> CrossCoupled<L> {
    /// All three laws at rest (axes at `position_um`, contour law at 0).
    pub fn at_rest(mut x: L, mut y: L, mut contour: L, position_um: [PosUm; 2]) -> Self {
        let [px, py] = position_um;
        x.reset(px);
        y.reset(py);
        contour.reset(PosUm::ZERO);
        Self {
            x,
            y,
            contour,
            feedforward_lsb: [CmdLsb::ZERO; 2],
        }
    }

    /// Sets the feed-forward commands `[X, Y]` (LSB, e.g. from
    /// [`super::feedforward::VelocityFf`]) that every following tick adds to the axis
    /// laws' outputs: `U1 = u1 + u_ff1 − C1·u_c`, `U2 = u2 + u_ff2 + C2·u_c`.
    #[inline]
    pub fn set_feedforward(&mut self, feedforward_lsb: [CmdLsb; 2]) {
        self.feedforward_lsb = feedforward_lsb;
    }

    fn axes(
        &mut self,
        c: &XyCoeffs<L::Coeffs>,
        reference_um: [PosUm; 2],
        measured_um: [PosUm; 2],
    ) -> [CmdLsb; 2] {
        let [rx, ry] = reference_um;
        let [mx, my] = measured_um;
        let [fx, fy] = self.feedforward_lsb;
        [
            self.x.track(&c.x, rx, mx).saturating_add(fx),
            self.y.track(&c.y, ry, my).saturating_add(fy),
        ]
    }

    /// Independent axes; ε from the model at `frame` is reported, not used.
    #[inline]
    pub fn tick_independent(
        &mut self,
        c: &XyCoeffs<L::Coeffs>,
        reference_um: [PosUm; 2],
        measured_um: [PosUm; 2],
        frame: &PathFrame,
    ) -> XyOutput {
        let [u1, u2] = self.axes(c, reference_um, measured_um);
        let [e1, e2] = errors(reference_um, measured_um);
        let m = contour_model(frame, e1, e2);
        XyOutput {
            command: [clamp_cmd(u1), clamp_cmd(u2)],
            contour_error_um: pos_from_q16(m.error_um_q16),
            contour_command: CmdLsb::ZERO,
        }
    }

    /// Cross-coupled with the line/circle model at V (`frame`: tangent and curvature at
    /// the reference point).
    #[inline]
    pub fn tick_model(
        &mut self,
        c: &XyCoeffs<L::Coeffs>,
        reference_um: [PosUm; 2],
        measured_um: [PosUm; 2],
        frame: &PathFrame,
    ) -> XyOutput {
        let [u1, u2] = self.axes(c, reference_um, measured_um);
        let [e1, e2] = errors(reference_um, measured_um);
        let m = contour_model(frame, e1, e2);
        let eps = pos_from_q16(m.error_um_q16);
        let uc = self.contour.regulate(&c.contour, eps);
        XyOutput {
            command: [
                distribute(u1, m.c1_q30.saturating_neg(), uc),
                distribute(u2, m.c2_q30, uc),
            ],
            contour_error_um: eps,
            contour_command: uc,
        }
    }

    /// Cross-coupled with an estimated signed contour error (our sign convention:
    /// > 0 right of travel) and the path frame at the estimate's foot point.
    #[inline]
    pub fn tick_estimated(
        &mut self,
        c: &XyCoeffs<L::Coeffs>,
        reference_um: [PosUm; 2],
        measured_um: [PosUm; 2],
        contour_error_um: PosUm,
        foot_frame: &PathFrame,
    ) -> XyOutput {
        let [u1, u2] = self.axes(c, reference_um, measured_um);
        let uc = self.contour.regulate(&c.contour, contour_error_um);
        XyOutput {
            command: [
                distribute_unit(u1, foot_frame.sin_q30.saturating_neg(), uc),
                distribute_unit(u2, foot_frame.cos_q30, uc),
            ],
            contour_error_um,
            contour_command: uc,
        }
    }
}

fn clamp_cmd(u: CmdLsb) -> CmdLsb {
    cmd_from_q16(i64::from(u.to_bits()).clamp(-U_MAX_Q16, U_MAX_Q16))
}

/// `[E1, E2] = V − P`, µm Q16.
fn errors(reference_um: [PosUm; 2], measured_um: [PosUm; 2]) -> [i64; 2] {
    let [rx, ry] = reference_um;
    let [mx, my] = measured_um;
    [
        q16_from_pos(rx).saturating_sub(q16_from_pos(mx)),
        q16_from_pos(ry).saturating_sub(q16_from_pos(my)),
    ]
}

#[cfg(test)]
mod tests;
