use super::super::contour_model::exact;
use super::super::fal::FalConfig;
use super::super::fhan::FhanConfig;
use super::super::npid::{NpidCoeffs, NpidConfig};
use super::super::pid::{PidCoeffs, PidConfig};
use super::*;
use proptest::prelude::*;

fn pid(kp: f64, ki: f64) -> PidCoeffs {
    PidConfig {
        period_s: 1e-3,
        kp_lsb_per_um: kp,
        ki_lsb_per_um_s: ki,
        kd_lsb_s_per_um: 0.0,
        derivative_filter_s: 2e-3,
        integral_limit_lsb: 300.0,
        output_limit_lsb: 2047.0,
    }
    .build()
    .unwrap()
}

fn npid(b0: f64, b1: f64, b2: f64) -> NpidCoeffs {
    let td = FhanConfig {
        r_um_per_s2: 5e7,
        h0_s: 2e-3,
    };
    NpidConfig {
        period_s: 1e-3,
        td_reference: td,
        td_measurement: td,
        beta0: b0,
        beta1: b1,
        beta2: b2,
        fal0: FalConfig {
            alpha: 1.0,
            delta: 1.0,
        },
        fal1: FalConfig {
            alpha: 0.8,
            delta: 20.0,
        },
        fal2: FalConfig {
            alpha: 1.0,
            delta: 1.0,
        },
        integral_limit_um_s: 200.0,
        output_limit_lsb: 2047.0,
    }
    .build()
    .unwrap()
}

fn um(x: f64) -> PosUm {
    PosUm::from_num(x)
}

/// On a CCW circle (and a CW one, and a line) the contour correction points from P back
/// toward the path, and ε has the sign of the exact signed distance.
#[test]
fn correction_points_back_to_the_path() {
    let r = 50_000.0;
    let centre = [0.0, 0.0];
    for ccw in [true, false] {
        for k in 0..16 {
            let phi = f64::from(k) * 0.39;
            let v = [r * phi.cos(), r * phi.sin()];
            let (t, kappa) = if ccw {
                ([-phi.sin(), phi.cos()], 1.0 / r)
            } else {
                ([phi.sin(), -phi.cos()], -1.0 / r)
            };
            let frame = PathFrame::from_f64(t[0], t[1], kappa);
            for &dr in &[-30.0, 30.0] {
                // P radially displaced by dr and lagging 200 µm along the path.
                let p = [
                    v[0] + dr * phi.cos() - 200.0 * t[0],
                    v[1] + dr * phi.sin() - 200.0 * t[1],
                ];
                let want = exact::circle(centre, r, ccw, p);
                let zero = pid(0.0, 0.0);
                let c = XyCoeffs {
                    x: zero,
                    y: zero,
                    contour: pid(1.0, 0.0),
                };
                let mut ccc = Ccc::default();
                let out = ccc.tick_model(&c, [um(v[0]), um(v[1])], [um(p[0]), um(p[1])], &frame);
                let eps = out.contour_error_um.to_num::<f64>();
                assert_eq!(eps.signum(), want.signum(), "ε {eps} vs exact {want}");
                assert!((eps - want).abs() < 1.0, "ε {eps} vs exact {want}");
                // The command moves P toward the path: U·(P − centre)·σ < 0.
                let u = [
                    out.command[0].to_num::<f64>(),
                    out.command[1].to_num::<f64>(),
                ];
                let radial = [p[0] - centre[0], p[1] - centre[1]];
                let outward = (u[0] * radial[0] + u[1] * radial[1]) * want.signum();
                let sigma = if ccw { 1.0 } else { -1.0 };
                assert!(
                    outward * sigma < 0.0,
                    "correction {u:?} does not reduce ε {want}"
                );
            }
        }
    }
}

/// Axis model for the closed-loop tests: a valve-controlled cylinder as a velocity
/// source behind a 1st-order spool lag, one period of computation delay.
struct Axis {
    x_um: f64,
    spool: f64,
    kv_um_per_s_per_lsb: f64,
    tau_s: f64,
    pending: f64,
}

impl Axis {
    fn step(&mut self, u_lsb: f64, load_um_per_s: f64) {
        let applied = self.pending;
        self.pending = u_lsb;
        for _ in 0..10 {
            let dt = 1e-4;
            self.spool += (applied - self.spool) * dt / self.tau_s;
            self.x_um += (self.kv_um_per_s_per_lsb * self.spool - load_um_per_s) * dt;
        }
    }
}

/// Runs a circle with the given controller; returns (max |exact ε|, max |tracking error|)
/// after the first 0.3 s, or None if anything left the bounds (diverged).
fn run_circle<L: ErrorLaw + Copy>(
    mut ctl: CrossCoupled<L>,
    c: &XyCoeffs<L::Coeffs>,
    coupled: bool,
) -> Option<(f64, f64)> {
    let (r, v) = (50_000.0, 50_000.0);
    let w = v / r;
    ctl = CrossCoupled::at_rest(ctl.x, ctl.y, ctl.contour, [um(r), um(0.0)]);
    let mut ax = Axis {
        x_um: r,
        spool: 0.0,
        kv_um_per_s_per_lsb: 58.6,
        tau_s: 3e-3,
        pending: 0.0,
    };
    let mut ay = Axis {
        x_um: 0.0,
        spool: 0.0,
        kv_um_per_s_per_lsb: 0.7 * 58.6,
        tau_s: 4.5e-3,
        pending: 0.0,
    };
    let (mut worst_c, mut worst_t) = (0.0f64, 0.0f64);
    for k in 0..4000 {
        let t = f64::from(k) * 1e-3;
        let phi = w * t;
        let reference = [um(r * phi.cos()), um(r * phi.sin())];
        let frame = PathFrame::from_f64(-phi.sin(), phi.cos(), 1.0 / r);
        let meas = [um(ax.x_um.round()), um(ay.x_um.round())];
        let out = if coupled {
            ctl.tick_model(c, reference, meas, &frame)
        } else {
            ctl.tick_independent(c, reference, meas, &frame)
        };
        // A 500 µm/s disturbance on X from 2 s (a load step).
        let load = if t > 2.0 { 500.0 } else { 0.0 };
        ax.step(out.command[0].to_num::<f64>(), load);
        ay.step(out.command[1].to_num::<f64>(), 0.0);
        let eps = exact::circle([0.0, 0.0], r, true, [ax.x_um, ay.x_um]);
        let et = (reference[0].to_num::<f64>() - ax.x_um)
            .abs()
            .max((reference[1].to_num::<f64>() - ay.x_um).abs());
        if !(eps.is_finite() && et < 1e6) {
            return None;
        }
        if t > 0.3 {
            worst_c = worst_c.max(eps.abs());
            worst_t = worst_t.max(et);
        }
    }
    Some((worst_c, worst_t))
}

#[test]
fn coupling_reduces_the_contour_error_on_the_test_plant() {
    let c = XyCoeffs {
        x: pid(0.5, 5.0),
        y: pid(0.5, 5.0),
        contour: pid(1.0, 10.0),
    };
    let (ind, _) = run_circle(Ccc::default(), &c, false).unwrap();
    let (ccc, _) = run_circle(Ccc::default(), &c, true).unwrap();
    assert!(ccc < 0.5 * ind, "CCC {ccc} µm vs independent {ind} µm");
    let n = XyCoeffs {
        x: npid(5.0, 0.8, 0.002),
        y: npid(5.0, 0.8, 0.002),
        contour: npid(10.0, 1.6, 0.002),
    };
    let (cnp, _) = run_circle(Cnp::default(), &n, true).unwrap();
    assert!(cnp < 0.5 * ind, "CNP {cnp} µm vs independent {ind} µm");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Over the documented gain range (axis kp 0.1 … 1 LSB/µm, ki ≤ 10·kp /s, contour
    /// gain ≤ 2× the axis gain) the coupled loop stays bounded.
    #[test]
    fn linear_ccc_bounded(kp in 0.1f64..1.0, ki_ratio in 0.0f64..10.0, kc in 0.0f64..2.0) {
        let c = XyCoeffs {
            x: pid(kp, ki_ratio * kp),
            y: pid(kp, ki_ratio * kp),
            contour: pid(kc * kp, ki_ratio * kc * kp),
        };
        let r = run_circle(Ccc::default(), &c, true);
        prop_assert!(r.is_some());
        let (eps, et) = r.unwrap_or_default();
        prop_assert!(eps < 5_000.0 && et < 20_000.0, "ε {} e {}", eps, et);
    }

    /// The same for the nonlinear PID (β1 0.5 … 3, β0 ≤ 10·β1, β2 ≤ 0.004, contour
    /// gains ≤ 2× the axis gains).
    #[test]
    fn nonlinear_cnp_bounded(
        b1 in 0.5f64..3.0, b0r in 0.0f64..10.0, b2 in 0.0f64..0.004, kc in 0.0f64..2.0,
    ) {
        let ax = npid(b0r * b1, b1, b2);
        let c = XyCoeffs { x: ax, y: ax, contour: npid(kc * b0r * b1, kc * b1, kc * b2) };
        let r = run_circle(Cnp::default(), &c, true);
        prop_assert!(r.is_some());
        let (eps, et) = r.unwrap_or_default();
        prop_assert!(eps < 5_000.0 && et < 20_000.0, "ε {} e {}", eps, et);
    }
}

proptest! {
    /// The 32-bit distribution of `tick_estimated` equals the 64-bit one.
    #[test]
    fn distribute_unit_is_distribute(
        u in any::<i32>(), g in -(1i32 << 30)..=(1i32 << 30), uc in any::<i32>(),
    ) {
        let (u, uc) = (CmdLsb::from_bits(u), CmdLsb::from_bits(uc));
        prop_assert_eq!(distribute_unit(u, g, uc), distribute(u, i64::from(g), uc));
    }
}
