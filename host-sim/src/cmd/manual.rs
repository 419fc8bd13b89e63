//! Moving slaves by hand from the host: `motion jog`, `motion move`, `motion start
//! --approach` (the board's `Manual` state, `hydra_core::runtime::manual`).
//!
//! - **jog** renews the board's Jog every 100 ms for `--seconds` (default: until the
//!   process is stopped — the board's 300 ms deadman then brakes the slave to rest, so a
//!   killed or crashed host never leaves an axis running), then sends speed 0 and waits
//!   for rest;
//! - **move** sends MoveTo and returns when the slave's S-curve has ended and it is within
//!   `--in-position-mm` of the target (a fault or a timeout is an error);
//! - **start --approach** moves every slave to the table at the present master, then the
//!   board starts following; returns when it follows.
//!
//! Defaults for commissioning (slow and soft; every value is the board's to refuse):
//! 10 mm/s, 100 mm/s², 1 000 mm/s³.

use super::motion::What;
use super::serial::Link;
use super::status::{fetch_on, Report};
use hydra_core::protocol::msg::MotionLimitsMsg;
use hydra_core::protocol::Request;
use std::time::{Duration, Instant};

/// The host renews a jog this often (the board's deadman is 300 ms).
pub const JOG_RENEW: Duration = Duration::from_millis(100);

/// A Status read right after a command may predate it (the board publishes its status
/// every few ms): a state other than the expected one is believed only after this.
const STALE: Duration = Duration::from_millis(200);

/// Options of the manual motions.
#[derive(Debug, Default, clap::Args)]
pub struct ManualArgs {
    /// Jog: target speed, mm/s (signed; 0 brakes to rest).
    #[arg(long, allow_negative_numbers = true)]
    pub speed_mm_s: Option<f64>,
    /// Jog: how long, s (default: until the process is stopped). Test: the test's
    /// length [1.8].
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Move: target position, mm.
    #[arg(long, allow_negative_numbers = true)]
    pub to_mm: Option<f64>,
    /// Move / approach: velocity limit, mm/s [default 10].
    #[arg(long)]
    pub vmax: Option<f64>,
    /// Acceleration limit, mm/s² [default 100].
    #[arg(long)]
    pub amax: Option<f64>,
    /// Jerk limit, mm/s³ [default 1000].
    #[arg(long)]
    pub jerk: Option<f64>,
    /// Move: the slave is "there" within this distance of the target, mm [default 0.05].
    #[arg(long)]
    pub in_position_mm: Option<f64>,
    /// Move / approach: give up after this long, s [default: a move's planned time + 10 s;
    /// an approach 120 s].
    #[arg(long)]
    pub timeout_s: Option<f64>,
    /// Start: first move every slave to the table at the present master, then follow.
    #[arg(long)]
    pub approach: bool,
}

/// A positive limit in mm-units as the board's µm-units integer.
fn um_limit(name: &str, v: Option<f64>, default_mm: f64) -> anyhow::Result<u32> {
    let mm = v.unwrap_or(default_mm);
    anyhow::ensure!(
        mm.is_finite() && mm > 0.0 && mm * 1000.0 <= f64::from(u32::MAX),
        "--{name} {mm}: must be > 0 and at most {} (mm-based units)",
        f64::from(u32::MAX) / 1000.0
    );
    Ok((mm * 1000.0).round().max(1.0) as u32)
}

impl ManualArgs {
    /// The limits (with the defaults).
    pub fn limits(&self) -> anyhow::Result<MotionLimitsMsg> {
        Ok(MotionLimitsMsg {
            vel_um_per_s: um_limit("vmax", self.vmax, 10.0)?,
            acc_um_per_s2: um_limit("amax", self.amax, 100.0)?,
            jerk_um_per_s3: um_limit("jerk", self.jerk, 1000.0)?,
        })
    }

    /// The jog speed, `I24F8` µm/s raw.
    pub fn speed(&self) -> anyhow::Result<i32> {
        let v = self
            .speed_mm_s
            .ok_or_else(|| anyhow::anyhow!("jog needs --speed-mm-s V"))?;
        anyhow::ensure!(
            v.is_finite() && v.abs() <= 8000.0,
            "--speed-mm-s {v}: must be within ±8000 mm/s"
        );
        Ok((v * 1000.0 * 256.0).round() as i32)
    }

    fn in_position_um(&self) -> anyhow::Result<f64> {
        let w = self.in_position_mm.unwrap_or(0.05);
        anyhow::ensure!(
            w.is_finite() && w > 0.0,
            "--in-position-mm {w}: must be > 0"
        );
        Ok(w * 1000.0)
    }
}

/// Refuses options that do not belong to `what` (so none is silently ignored).
pub fn check_args(what: What, m: &ManualArgs) -> anyhow::Result<()> {
    let jog = m.speed_mm_s.is_some() || m.seconds.is_some();
    let moving = m.to_mm.is_some() || m.in_position_mm.is_some();
    let limits = m.vmax.is_some() || m.amax.is_some() || m.jerk.is_some();
    let ok = match what {
        What::Jog => !moving && m.vmax.is_none() && !m.approach && m.timeout_s.is_none(),
        What::Test => {
            m.speed_mm_s.is_none() && !moving && !limits && !m.approach && m.timeout_s.is_none()
        }
        What::Move => !jog && !m.approach,
        What::Start => !jog && !moving && (m.approach || (!limits && m.timeout_s.is_none())),
        _ => !jog && !moving && !limits && !m.approach && m.timeout_s.is_none(),
    };
    anyhow::ensure!(
        ok,
        "{what:?} does not take these options (jog: --speed-mm-s --seconds --amax --jerk; \
         move: --to-mm --vmax --amax --jerk --in-position-mm --timeout-s; start --approach: \
         --vmax --amax --jerk --timeout-s; test: --seconds and the test's options)"
    );
    if let Some(s) = m.seconds {
        anyhow::ensure!(s.is_finite() && s > 0.0, "--seconds {s}: must be > 0");
    }
    Ok(())
}

/// The Jog request.
pub fn jog_request(axis: u8, m: &ManualArgs, speed: i32) -> anyhow::Result<Request<'static>> {
    Ok(Request::Jog {
        axis,
        speed,
        limits: m.limits()?,
    })
}

/// The MoveTo request.
pub fn move_request(axis: u8, m: &ManualArgs) -> anyhow::Result<Request<'static>> {
    let to = m
        .to_mm
        .ok_or_else(|| anyhow::anyhow!("move needs --to-mm X"))?;
    anyhow::ensure!(
        to.is_finite() && to.abs() <= 8000.0,
        "--to-mm {to}: a position must be within ±8000 mm"
    );
    Ok(Request::MoveTo {
        axis,
        to_um: (to * 1000.0 * 256.0).round() as i32,
        limits: m.limits()?,
    })
}

fn axis_of(r: &Report, axis: u8) -> anyhow::Result<&super::status::AxisReport> {
    r.axes
        .get(usize::from(axis))
        .ok_or_else(|| anyhow::anyhow!("the board reports no slave {axis}"))
}

fn fault_error(r: &Report) -> anyhow::Error {
    anyhow::anyhow!(
        "the board faulted: {}",
        r.fault_name.as_deref().unwrap_or("unknown fault")
    )
}

/// Jogs: renews every 100 ms for `--seconds` (or until stopped), then brakes to rest.
pub fn jog(link: &mut Link, axis: u8, m: &ManualArgs) -> anyhow::Result<()> {
    let q = jog_request(axis, m, m.speed()?)?;
    let until = m
        .seconds
        .map(|s| Instant::now() + Duration::from_secs_f64(s));
    let mut shown = Instant::now();
    while until.is_none_or(|t| Instant::now() < t) {
        link.expect_ack(&q)?;
        if shown.elapsed() >= Duration::from_millis(500) {
            let r = fetch_on(link)?;
            let a = axis_of(&r, axis)?;
            println!("axis {axis} at {:.3} mm ({})", a.pos_mm, a.manual);
            shown = Instant::now();
        }
        std::thread::sleep(JOG_RENEW);
    }
    link.expect_ack(&jog_request(axis, m, 0)?)?;
    let t0 = Instant::now();
    loop {
        let r = fetch_on(link)?;
        if r.state == "fault" {
            return Err(fault_error(&r));
        }
        let a = axis_of(&r, axis)?;
        if a.manual == "hold" {
            println!("axis {axis} at rest at {:.3} mm", a.pos_mm);
            return Ok(());
        }
        anyhow::ensure!(
            t0.elapsed() < Duration::from_secs(30),
            "axis {axis} did not come to rest within 30 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The planned duration of a move of `d_um` under `l`, s (the host's copy of the board's
/// plan: `hydra_core::scurve::Plan`).
fn planned_s(d_um: f64, l: &MotionLimitsMsg) -> f64 {
    let lim = hydra_core::scurve::Limits {
        vel_lsb_per_s: f64::from(l.vel_um_per_s) * 256.0,
        acc_lsb_per_s2: f64::from(l.acc_um_per_s2) * 256.0,
        jerk_lsb_per_s3: f64::from(l.jerk_um_per_s3) * 256.0,
    };
    hydra_core::scurve::Plan::new((d_um.abs() * 256.0) as u64, &lim)
        .map(|p| p.duration_s())
        .unwrap_or(0.0)
}

/// Waits until slave `axis` ended its move and is within the in-position window of
/// `to_um` (I24F8 raw).
pub fn wait_in_position(
    link: &mut Link,
    axis: u8,
    to_um: i32,
    m: &ManualArgs,
) -> anyhow::Result<()> {
    let to = f64::from(to_um) / 256.0;
    let window = m.in_position_um()?;
    let r = fetch_on(link)?;
    let from = axis_of(&r, axis)?.pos_mm * 1000.0;
    let timeout = m
        .timeout_s
        .unwrap_or_else(|| planned_s(to - from, &m.limits().unwrap_or_default()) + 10.0);
    let t0 = Instant::now();
    loop {
        let r = fetch_on(link)?;
        if r.state == "fault" {
            return Err(fault_error(&r));
        }
        let a = axis_of(&r, axis)?;
        let off = (a.pos_mm * 1000.0 - to).abs();
        if r.state != "manual" && t0.elapsed() < STALE {
            std::thread::sleep(Duration::from_millis(10));
            continue;
        }
        if r.state != "manual" {
            anyhow::bail!(
                "the board left manual control ({}) before the move ended",
                r.state
            );
        }
        if a.manual == "hold" && off <= window {
            println!(
                "axis {axis} at {:.3} mm (target {:.3} mm, {:.1} µm off) after {:.2} s",
                a.pos_mm,
                to / 1000.0,
                off,
                t0.elapsed().as_secs_f64()
            );
            return Ok(());
        }
        anyhow::ensure!(
            t0.elapsed().as_secs_f64() < timeout,
            "axis {axis} not within {:.3} mm of {:.3} mm after {timeout:.1} s (at {:.3} mm)",
            window / 1000.0,
            to / 1000.0,
            a.pos_mm
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Waits until the board follows after an approach.
pub fn wait_following(link: &mut Link, m: &ManualArgs) -> anyhow::Result<()> {
    let timeout = m.timeout_s.unwrap_or(120.0);
    let t0 = Instant::now();
    loop {
        let r = fetch_on(link)?;
        match r.state.as_str() {
            "following" => {
                println!(
                    "following after a {:.2} s approach",
                    t0.elapsed().as_secs_f64()
                );
                return Ok(());
            }
            "fault" => return Err(fault_error(&r)),
            "manual" if t0.elapsed() >= STALE && r.axes.iter().all(|a| a.manual == "hold") => {
                anyhow::bail!(
                    "the master moved during the approach (beyond the resume window): the slaves \
                 hold at the table's old position in manual; run start --approach again"
                )
            }
            "manual" => {}
            _ if t0.elapsed() < STALE => {}
            s => anyhow::bail!("the board is {s}, not approaching"),
        }
        anyhow::ensure!(
            t0.elapsed().as_secs_f64() < timeout,
            "not following after {timeout:.0} s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}
