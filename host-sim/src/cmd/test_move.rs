//! `host-sim motion test --port P --axis N --profile step|chirp|prbs --csv REC.csv`:
//! the board's identification test move (`hydra_core::runtime::test_move`) recorded
//! by the loop-rate capture, for `host-sim identify --trace REC.csv`.
//!
//! Arms the capture on the command's tick (20 ms before it, the test and 150 ms
//! after), sends TestMove (the slave must be referenced, at rest, in Idle or Manual;
//! the board refuses a test that would leave the axis' limits or exceed its top speed),
//! waits for the capture and writes it as `capture` does (one row per tick: the
//! valve command, position and both pressures of every slave). The board holds the slave
//! at its start position afterwards, in Manual (`motion stop` → Idle).
//!
//! Defaults (a small, safe excitation on the reference machine): step ±1 mm with 250 ms
//! levels, PRBS ±0.5 mm with 20 ms bits, chirp ±0.5 mm from 1 to 20 Hz; 1.8 s (the
//! board records 2 048 ticks: 2.048 s at 1 ms).

use super::capture::{arm, collect, csv, plot};
use super::serial::Link;
use hydra_core::protocol::msg::TestMoveMsg;
use hydra_core::protocol::Request;
use hydra_core::runtime::{TestProfile, TestSpec, Trigger};
use std::path::PathBuf;
use std::time::Duration;

/// The test's shape (`--profile`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Profile {
    /// +A, 0, −A, 0 … each held `--dwell-ms`.
    Step,
    /// A sine sweep from `--f0-hz` to `--f1-hz`.
    Chirp,
    /// ±A from a maximum-length sequence, one bit per `--dwell-ms`.
    Prbs,
}

/// Options of `motion test`.
#[derive(Debug, Default, clap::Args)]
pub struct TestArgs {
    /// Test: the excitation.
    #[arg(long, value_enum)]
    pub profile: Option<Profile>,
    /// Test: amplitude about the slave's position, mm [step 1, prbs and chirp 0.5].
    #[arg(long)]
    pub amplitude_mm: Option<f64>,
    /// Test: time per level, ms [step 250, prbs 20].
    #[arg(long)]
    pub dwell_ms: Option<f64>,
    /// Test (chirp): start frequency, Hz [1].
    #[arg(long)]
    pub f0_hz: Option<f64>,
    /// Test (chirp): end frequency, Hz [20].
    #[arg(long)]
    pub f1_hz: Option<f64>,
    /// Test: the capture's CSV (`identify --trace`).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Test: an SVG plot of the capture.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

impl TestArgs {
    /// Whether any test option is given (refused on other commands).
    pub fn any(&self) -> bool {
        self.profile.is_some()
            || self.amplitude_mm.is_some()
            || self.dwell_ms.is_some()
            || self.f0_hz.is_some()
            || self.f1_hz.is_some()
            || self.csv.is_some()
            || self.plot.is_some()
    }

    /// The spec (defaults in the module docs) for a test of `seconds`.
    pub fn spec(&self, seconds: Option<f64>) -> anyhow::Result<TestSpec> {
        let profile = self
            .profile
            .ok_or_else(|| anyhow::anyhow!("test needs --profile step|chirp|prbs"))?;
        let int = |name: &str, v: f64, scale: f64, max: f64| -> anyhow::Result<u32> {
            let x = (v * scale).round();
            anyhow::ensure!(
                v.is_finite() && x >= 1.0 && x <= max,
                "--{name} {v}: must be > 0 and at most {}",
                max / scale
            );
            Ok(x as u32)
        };
        let (amp, dwell) = match profile {
            Profile::Step => (1.0, 250.0),
            Profile::Prbs => (0.5, 20.0),
            Profile::Chirp => (0.5, 0.0),
        };
        let per_level = profile != Profile::Chirp;
        anyhow::ensure!(
            per_level || self.dwell_ms.is_none(),
            "--dwell-ms is for step and prbs (a chirp sweeps --f0-hz … --f1-hz)"
        );
        anyhow::ensure!(
            !per_level || (self.f0_hz.is_none() && self.f1_hz.is_none()),
            "--f0-hz / --f1-hz are for a chirp"
        );
        Ok(TestSpec {
            profile: match profile {
                Profile::Step => TestProfile::Step,
                Profile::Chirp => TestProfile::Chirp,
                Profile::Prbs => TestProfile::Prbs,
            },
            amplitude_um: int(
                "amplitude-mm",
                self.amplitude_mm.unwrap_or(amp),
                1000.0,
                1e5,
            )?,
            duration_ms: int("seconds", seconds.unwrap_or(1.8), 1000.0, 6e4)?,
            dwell_ms: if per_level {
                int("dwell-ms", self.dwell_ms.unwrap_or(dwell), 1.0, 6e4)?
            } else {
                0
            },
            f_start_mhz: if per_level {
                0
            } else {
                int("f0-hz", self.f0_hz.unwrap_or(1.0), 1000.0, 1e6)?
            },
            f_end_mhz: if per_level {
                0
            } else {
                int("f1-hz", self.f1_hz.unwrap_or(20.0), 1000.0, 1e6)?
            },
        })
    }
}

/// Runs the test on slave `axis` and writes the capture.
pub fn run(link: &mut Link, axis: u8, t: &TestArgs, seconds: Option<f64>) -> anyhow::Result<()> {
    let spec = t.spec(seconds)?;
    let out = t
        .csv
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("test needs --csv REC.csv (the recording)"))?;
    for p in std::iter::once(out).chain(t.plot.iter()) {
        crate::csvout::writable(p)?;
    }
    let post_ms = f64::from(spec.duration_ms) + 150.0;
    arm(link, Trigger::Command, 20.0, post_ms).map_err(|e| {
        e.context(format!(
            "arming the capture for a {:.2} s test (shorten --seconds to what the board records)",
            f64::from(spec.duration_ms) * 1e-3
        ))
    })?;
    if let Err(e) = link.expect_ack(&Request::TestMove {
        axis,
        test: TestMoveMsg::of(&spec),
    }) {
        // Refused: the capture armed for it must not fire on the next command (someone
        // else's). A capture triggered now replaces it (the board keeps one capture).
        let _ = arm(link, Trigger::Now, 0.0, 0.0);
        return Err(e);
    }
    eprintln!(
        "test running on slave {axis} ({:?}, ±{:.3} mm, {:.2} s) …",
        spec.profile,
        f64::from(spec.amplitude_um) * 1e-3,
        f64::from(spec.duration_ms) * 1e-3
    );
    let c = collect(link, Duration::from_secs_f64(post_ms * 1e-3 + 10.0))?;
    crate::csvout::save(out, &csv(&c)?)?;
    let a = usize::from(axis);
    let moved: Vec<f64> = c
        .rows
        .iter()
        .filter_map(|r| r.axes.get(a).map(|x| f64::from(x.actual_um) / 256_000.0))
        .collect();
    let (lo, hi) = moved
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
            (l.min(x), h.max(x))
        });
    let faulted = c
        .rows
        .iter()
        .any(|r| r.flags & hydra_core::runtime::STATE_MASK == 3);
    eprintln!(
        "{} ticks → {} (slave {axis} between {lo:.3} and {hi:.3} mm)",
        c.rows.len(),
        out.display()
    );
    if let Some(p) = &t.plot {
        plot(&c, p, &format!("test move, slave {axis}"))?;
        eprintln!("plot → {}", p.display());
    }
    if faulted {
        let why = super::status::fetch_on(link)
            .ok()
            .and_then(|r| r.fault_name)
            .unwrap_or_else(|| "see host-sim status".into());
        anyhow::bail!(
            "the board faulted during the test ({why}); the recording was written. Lower \
             the gains (param set axis/{axis}/kp_lsb_per_um …) or the amplitude, clear the \
             fault and repeat"
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_and_the_refusals_of_a_test_spec() {
        let t = TestArgs {
            profile: Some(Profile::Chirp),
            ..Default::default()
        };
        let s = t.spec(None).unwrap();
        assert_eq!(
            (s.amplitude_um, s.duration_ms, s.f_start_mhz, s.f_end_mhz),
            (500, 1800, 1000, 20_000)
        );
        let t = TestArgs {
            profile: Some(Profile::Step),
            amplitude_mm: Some(2.0),
            ..Default::default()
        };
        let s = t.spec(Some(1.0)).unwrap();
        assert_eq!(
            (s.amplitude_um, s.duration_ms, s.dwell_ms),
            (2000, 1000, 250)
        );
        assert!(TestArgs::default().spec(None).is_err(), "no profile");
        for bad in [
            TestArgs {
                profile: Some(Profile::Step),
                amplitude_mm: Some(-1.0),
                ..Default::default()
            },
            TestArgs {
                profile: Some(Profile::Prbs),
                amplitude_mm: Some(f64::NAN),
                ..Default::default()
            },
            TestArgs {
                profile: Some(Profile::Step),
                f1_hz: Some(5.0),
                ..Default::default()
            },
            TestArgs {
                profile: Some(Profile::Chirp),
                dwell_ms: Some(5.0),
                ..Default::default()
            },
        ] {
            assert!(bad.spec(None).is_err(), "{bad:?}");
        }
        let step = TestArgs {
            profile: Some(Profile::Step),
            ..Default::default()
        };
        assert!(step.spec(Some(0.0)).is_err());
        assert!(step.spec(Some(61.0)).is_err());
    }
}
