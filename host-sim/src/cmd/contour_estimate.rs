//! `host-sim contour-estimate`: runs the fixed-point interpolator of `hydra_xy::contour`
//! along a path, places actual points as a lagging servo would (behind the reference by
//! up to K periods along the path, off it by up to ±E µm along the normal), and compares
//! the adaptive estimator, the chord method and the tangent method with the exact signed
//! distance ([`crate::contour_truth`]).
//!
//! Paths (`--path`):
//! * `parabola` (default): y = x²/(2·10 mm), x ∈ [−20, 20] mm (radius of curvature
//!   10 mm at the vertex);
//! * `circle`: radius 10 mm, centre (0, 10 mm), one full counter-clockwise turn from the
//!   origin (start angle −90°);
//! * `line`: from (0, 0) to (40, 30) mm.
//!
//! Per period, `--points-per-tick` actual points are drawn (deterministic
//! pseudo-random, `--seed`): lag uniform in [0, K·ΔS] of arc length, offset uniform in
//! [−E, E] along the normal; each is rounded to the axes' `PosUm` (3.9 nm) before any
//! method sees it, and the exact distance is computed for that rounded point.
//! Sampling starts once K + 1 periods have run (the window then covers the lag).
//! Error of a method = its ε − exact ε (µm); reported: max |error| and RMS.

use crate::contour_truth::TruthPath;
use anyhow::{bail, Result};
use hydra_core::units::{PosUm, VelUmPerS};
use hydra_xy::contour::{
    ArcSpec, ContourWindow, InterpConfig, Interpolator, LineSpec, ParabolaSpec, ParametricPath, Xy,
};
use serde::Serialize;

/// Ordinary points the command's window holds.
const WINDOW_N: usize = 64;
/// Extra points per segment the command's window holds.
const WINDOW_H: usize = 255;

/// The built-in test paths.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PathKind {
    /// Straight line (0, 0) → (40, 30) mm.
    Line,
    /// Full circle, radius 10 mm.
    Circle,
    /// y = x²/(2·10 mm), x ∈ [−20, 20] mm.
    Parabola,
}

impl PathKind {
    fn name(self) -> &'static str {
        match self {
            PathKind::Line => "line",
            PathKind::Circle => "circle",
            PathKind::Parabola => "parabola",
        }
    }
}

/// Arguments of the sub-command.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Path to run.
    #[arg(long, value_enum, default_value_t = PathKind::Parabola)]
    pub path: PathKind,
    /// Feed along the path, mm/s (> 0, ≤ 8000).
    #[arg(long, value_name = "MM_PER_S", default_value_t = 200.0)]
    pub feed: f64,
    /// Servo period, µs (10 … 1 000 000).
    #[arg(long = "period-us", value_name = "N", default_value_t = 1000)]
    pub period_us: u32,
    /// Largest lag of the actual point behind the reference, in periods (≤ 60).
    #[arg(long = "lag-periods", value_name = "K", default_value_t = 10)]
    pub lag_periods: u32,
    /// Largest offset of the actual point from the path along the normal, µm.
    #[arg(long = "offset-um", value_name = "E", default_value_t = 50.0)]
    pub offset_um: f64,
    /// Q of h = ⌊Q·κ·v⌋, seconds.
    #[arg(long = "q-s", value_name = "Q", default_value_t = 1.0)]
    pub q_s: f64,
    /// Cap on the extra points per period (≤ 255).
    #[arg(long = "h-max", value_name = "H", default_value_t = 63)]
    pub h_max: u16,
    /// Actual points drawn per period.
    #[arg(long = "points-per-tick", value_name = "M", default_value_t = 8)]
    pub points_per_tick: u32,
    /// Seed of the deterministic point generator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

impl Default for Args {
    fn default() -> Self {
        Self {
            path: PathKind::Parabola,
            feed: 200.0,
            period_us: 1000,
            lag_periods: 10,
            offset_um: 50.0,
            q_s: 1.0,
            h_max: 63,
            points_per_tick: 8,
            seed: 1,
            json: false,
        }
    }
}

/// Error statistics of one method against the exact distance, µm.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Stats {
    /// Largest |ε_method − ε_exact|, µm.
    pub max_abs_error_um: f64,
    /// Root mean square of ε_method − ε_exact, µm.
    pub rms_error_um: f64,
}

/// The three methods' statistics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Methods {
    /// The adaptive estimator (extra points + bisection).
    pub adaptive: Stats,
    /// Distance to the polyline of the ordinary points.
    pub chord: Stats,
    /// Distance to the tangent line at the reference point.
    pub tangent: Stats,
}

/// The `--json` object.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// `line`, `circle` or `parabola`.
    pub path: String,
    /// Feed, mm/s.
    pub feed_mm_s: f64,
    /// Statistics per method.
    pub methods: Methods,
}

/// Run facts printed with the table (not part of the JSON object).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Details {
    /// Servo periods run.
    pub ticks: usize,
    /// Actual points compared.
    pub samples: usize,
    /// Fewest and most extra points in one period (over the periods that advanced).
    pub extra_min: u16,
    /// Most extra points in one period.
    pub extra_max: u16,
    /// Most bisection steps in one estimate.
    pub bisection_max: u8,
    /// Largest |exact ε| seen, µm.
    pub max_abs_exact_um: f64,
    /// The a-priori bound of the adaptive error (docs/contour.md), µm.
    pub bound_um: f64,
}

#[derive(Default)]
struct Acc {
    max: f64,
    sum2: f64,
    n: usize,
}

impl Acc {
    fn add(&mut self, e: f64) {
        self.max = self.max.max(e.abs());
        self.sum2 += e * e;
        self.n += 1;
    }

    fn stats(&self) -> Stats {
        Stats {
            max_abs_error_um: self.max,
            rms_error_um: if self.n == 0 {
                0.0
            } else {
                (self.sum2 / self.n as f64).sqrt()
            },
        }
    }
}

/// splitmix64: a small deterministic generator.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The specification of a built-in path (µm).
pub enum Spec {
    /// Straight line.
    Line(LineSpec),
    /// Circular arc.
    Arc(ArcSpec),
    /// Parabola.
    Parabola(ParabolaSpec),
}

/// The built-in path of a kind.
pub fn spec_of(kind: PathKind) -> Spec {
    match kind {
        PathKind::Line => Spec::Line(LineSpec {
            start_um: [0.0, 0.0],
            end_um: [40_000.0, 30_000.0],
        }),
        PathKind::Circle => Spec::Arc(ArcSpec {
            center_um: [0.0, 10_000.0],
            radius_um: 10_000.0,
            start_deg: -90.0,
            sweep_deg: 360.0,
        }),
        PathKind::Parabola => Spec::Parabola(ParabolaSpec {
            vertex_um: [0.0, 0.0],
            p_um: 10_000.0,
            axis_deg: 0.0,
            x_start_um: -20_000.0,
            x_end_um: 20_000.0,
        }),
    }
}

/// Runs the comparison (what the command prints).
pub fn evaluate(args: &Args) -> Result<(Report, Details)> {
    match spec_of(args.path) {
        Spec::Line(s) => {
            let path = s.build().map_err(|e| anyhow::anyhow!("line: {e:?}"))?;
            run_on(args, &path, &TruthPath::line(&s))
        }
        Spec::Arc(s) => {
            let path = s.build().map_err(|e| anyhow::anyhow!("circle: {e:?}"))?;
            run_on(args, &path, &TruthPath::arc(&s))
        }
        Spec::Parabola(s) => {
            let path = s.build().map_err(|e| anyhow::anyhow!("parabola: {e:?}"))?;
            run_on(args, &path, &TruthPath::parabola(&s))
        }
    }
}

/// Runs the comparison on any path with its `f64` ground truth (same parameter).
pub fn run_on<P: ParametricPath>(
    args: &Args,
    path: &P,
    truth: &TruthPath,
) -> Result<(Report, Details)> {
    if !(args.feed > 0.0 && args.feed <= 8000.0) {
        bail!("--feed must be in (0, 8000] mm/s, got {}", args.feed);
    }
    if args.lag_periods as usize + 4 > WINDOW_N {
        bail!(
            "--lag-periods must be at most {}, got {}",
            WINDOW_N - 4,
            args.lag_periods
        );
    }
    if !(args.offset_um >= 0.0 && args.offset_um <= 100_000.0) {
        bail!("--offset-um must be in [0, 100000], got {}", args.offset_um);
    }
    if usize::from(args.h_max) > WINDOW_H {
        bail!("--h-max must be at most {WINDOW_H}, got {}", args.h_max);
    }
    if args.points_per_tick == 0 {
        bail!("--points-per-tick must be at least 1");
    }
    let coeffs = InterpConfig {
        period_us: args.period_us,
        q_s: args.q_s as f32,
        h_max: args.h_max,
    }
    .build()
    .map_err(|e| anyhow::anyhow!("interpolator settings: {e:?} (--period-us / --q-s)"))?;
    let feed = VelUmPerS::from_num(args.feed * 1000.0);
    let ds_um = args.feed * 1000.0 * f64::from(args.period_us) * 1e-6;
    let k = args.lag_periods as usize;

    let mut window: Box<ContourWindow<WINDOW_N, WINDOW_H>> = Box::new(ContourWindow::new());
    let mut interp = Interpolator::start(path, &mut window);
    let mut rng = Rng(args.seed);
    let (mut ad, mut ch, mut ta) = (Acc::default(), Acc::default(), Acc::default());
    let mut det = Details {
        extra_min: u16::MAX,
        ..Details::default()
    };
    let (_, u_end) = truth.domain();
    let max_ticks = (truth.arc_length(u_end) / ds_um).ceil() as usize + 10;
    for tick in 1..=max_ticks {
        let r = interp.step(&coeffs, path, feed, &mut window);
        if !r.advanced {
            break;
        }
        det.ticks = tick;
        det.extra_min = det.extra_min.min(r.extra_points);
        det.extra_max = det.extra_max.max(r.extra_points);
        if tick > k {
            let u_ref = r.point.u.to_num::<f64>();
            for _ in 0..args.points_per_tick {
                let lag = rng.unit() * k as f64 * ds_um;
                let off = (2.0 * rng.unit() - 1.0) * args.offset_um;
                let u = truth.u_behind(u_ref, lag);
                let (base, n) = (truth.r(u), truth.left_normal(u));
                let p = Xy::new(
                    PosUm::from_num(base[0] + off * n[0]),
                    PosUm::from_num(base[1] + off * n[1]),
                );
                let exact = truth.nearest([p.x.to_num(), p.y.to_num()]).eps;
                let (Some(a), Some(c), Some(t)) = (
                    window.estimate(p),
                    window.estimate_chord(p),
                    window.estimate_tangent(p),
                ) else {
                    bail!("empty window");
                };
                ad.add(a.eps_um.to_num::<f64>() - exact);
                ch.add(c.eps_um.to_num::<f64>() - exact);
                ta.add(t.to_num::<f64>() - exact);
                det.bisection_max = det.bisection_max.max(a.bisection_steps);
                det.max_abs_exact_um = det.max_abs_exact_um.max(exact.abs());
                det.samples += 1;
            }
        }
        if r.finished {
            break;
        }
    }
    if det.samples == 0 {
        bail!("the path ended before any point could be placed: lower --lag-periods or --feed");
    }
    let kmax = truth.max_curvature();
    let ts = f64::from(args.period_us) * 1e-6;
    let v = args.feed * 1000.0;
    let hcap = f64::from(args.h_max) + 1.0;
    let sag = if args.q_s > 0.0 {
        (v * ts * ts / (8.0 * args.q_s)).max(ds_um * ds_um * kmax / (8.0 * hcap * hcap))
    } else {
        ds_um * ds_um * kmax / 8.0
    };
    det.bound_um = sag.min(ds_um * ds_um * kmax / 8.0) * (1.0 + args.offset_um * kmax);
    Ok((
        Report {
            path: args.path.name().to_string(),
            feed_mm_s: args.feed,
            methods: Methods {
                adaptive: ad.stats(),
                chord: ch.stats(),
                tangent: ta.stats(),
            },
        },
        det,
    ))
}

/// Runs the sub-command.
pub fn run(args: &Args) -> Result<()> {
    let (rep, det) = evaluate(args)?;
    if args.json {
        println!("{}", serde_json::to_string(&rep)?);
        return Ok(());
    }
    println!(
        "contour-estimate: {} at {} mm/s, Ts {} µs, lag ≤ {} periods, offset ≤ ±{} µm, Q {} s, h ≤ {}",
        rep.path,
        rep.feed_mm_s,
        args.period_us,
        args.lag_periods,
        args.offset_um,
        args.q_s,
        args.h_max
    );
    println!(
        "{} periods, {} points; extra points per period {}…{}; bisection ≤ {} steps; max |ε| {:.3} µm",
        det.ticks, det.samples, det.extra_min, det.extra_max, det.bisection_max, det.max_abs_exact_um
    );
    println!(
        "a-priori bound of the adaptive chord error: {:.4} µm",
        det.bound_um
    );
    println!(
        "{:<10} {:>16} {:>14} {:>14}",
        "method", "max |err| µm", "rms µm", "max / adaptive"
    );
    let a = rep.methods.adaptive.max_abs_error_um;
    for (name, s) in [
        ("adaptive", rep.methods.adaptive),
        ("chord", rep.methods.chord),
        ("tangent", rep.methods.tangent),
    ] {
        let ratio = if a > 0.0 {
            format!("{:.1}", s.max_abs_error_um / a)
        } else {
            "-".to_string()
        };
        println!(
            "{:<10} {:>16.5} {:>14.5} {:>14}",
            name, s.max_abs_error_um, s.rms_error_um, ratio
        );
    }
    Ok(())
}
