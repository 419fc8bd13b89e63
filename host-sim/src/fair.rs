//! The fair comparison: every controller tuned by the same procedure at each period,
//! then measured on the same run.
//!
//! The shipped gain sets come from the rule of [`crate::autotune`] (K_u from a P-only
//! step test, Kp = K_u/2, Ki = Kp²·K_vel/4), and the rule gives the three laws the same
//! feedback gains: a law that would follow better with less gain (the traditional PID,
//! whose node target jumps by millimetres and saturates the valve at full gain; the
//! paper's law, which settles a period ahead of the table) is shown at a disadvantage.
//! The procedure here is the same for every law and period:
//!
//! 1. The rule's set (`Kp_r`, `Ki_r` and the law's other gains; [`autotune::tune`]).
//! 2. A search over the feedback gains on the scenario's own run, with a ceiling from
//!    the step test: `Kp = f_p·Kp_r` for `f_p` ∈ [`KP_FACTORS`] (√2 … 1/16 in
//!    half-octaves: Kp ≤ 0.71·K_u, a gain margin of at least 3 dB — half the rule's 6 dB,
//!    which the shipped sets keep), and `Ki = f_i·Ki_r·f_p²` (the rule's PI corner at that
//!    Kp, scaled) for `f_i` ∈ [`KI_FACTORS`] (0, 1, 4, 16, 64, 256): 54 runs. A set the
//!    core refuses (Ki·T beyond its format at a long period) is no candidate.
//! 3. The set with the smallest largest tracking error of any follower axis (after
//!    `sim.error_skip_s`), among runs that latched no fault; ties by RMS.
//!
//! Every other gain (integrator zone and clamp, feed-forward, valve lag, master filter) is
//! the rule's. Force axes are left out of the search's runs (they do not affect the
//! followers: each axis has its own plant; only the master is shared).

use crate::autotune::{self, Margins};
use crate::camfile::CamCsv;
use crate::scenario::{Controller, Role, Scenario, ScenarioError, Tuning};
use crate::sim::{run as simulate, RunSpec};
use rayon::prelude::*;

/// Kp as a multiple of the rule's (half-octaves from √2 down to 1/16): at most
/// 0.71·K_u, a gain margin of at least 3 dB.
pub const KP_FACTORS: [f64; 9] = [
    std::f64::consts::SQRT_2,
    1.0,
    std::f64::consts::FRAC_1_SQRT_2,
    0.5,
    0.353_553_390_593_273_8,
    0.25,
    0.176_776_695_296_636_9,
    0.125,
    0.0625,
];

/// Ki as a multiple of the rule's PI corner at the chosen Kp (0 and 1 … 256 in
/// double octaves).
pub const KI_FACTORS: [f64; 6] = [0.0, 1.0, 4.0, 16.0, 64.0, 256.0];

/// One run's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Score {
    /// Kp of the first follower axis (by name), LSB/µm (every axis is scaled alike).
    pub kp_lsb_per_um: f64,
    /// Ki of the first follower axis (by name), LSB/(µm·s).
    pub ki_lsb_per_um_s: f64,
    /// Largest |error| of any follower axis, µm.
    pub max_um: f64,
    /// Largest RMS error of any follower axis, µm.
    pub rms_um: f64,
    /// The faults the run latched (a run with one is not chosen).
    pub faults: Vec<String>,
}

/// The procedure's outcome for one law at one period.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Fair {
    /// The law.
    pub controller: &'static str,
    /// The control period, µs.
    pub period_us: u32,
    /// The rule's set on its own (step 1).
    pub rule: Score,
    /// The chosen set (step 3).
    pub best: Score,
    /// Runs searched.
    pub runs: usize,
    /// The chosen gain set, every follower axis (as a scenario's `[[tuning]]`).
    #[serde(skip)]
    pub tuning: Tuning,
}

/// The scenario without its force axes (the followers' runs are the same without them).
fn followers_only(s: &Scenario) -> Scenario {
    let mut out = s.clone();
    out.axes.retain(|a| a.role == Role::Follower);
    for t in &mut out.tuning {
        t.press.clear();
    }
    out
}

/// `rule` with every follower axis' Kp and Ki scaled by `fp` and `fi` (step 2).
fn scaled(rule: &Tuning, fp: f64, fi: f64) -> Tuning {
    let mut t = rule.clone();
    for g in t.axes.values_mut() {
        g.kp_lsb_per_um = (f64::from(g.kp_lsb_per_um) * fp) as f32;
        g.ki_lsb_per_um_s = (f64::from(g.ki_lsb_per_um_s) * fi * fp * fp) as f32;
    }
    t
}

/// Runs `s` with gain set `t` (replacing the scenario's sets of its law).
fn score(s: &Scenario, table: &CamCsv, t: &Tuning) -> Result<Score, ScenarioError> {
    let mut run_s = s.clone();
    run_s.tuning.retain(|x| x.controller != t.controller);
    run_s.tuning.push(t.clone());
    let spec = RunSpec {
        controller: t.controller,
        period_us: t.period_us,
        trace_every_s: None,
    };
    let r = simulate(&run_s, table, &spec, &mut |_| {})?;
    let (max_um, rms_um, _) = r.followers_worst();
    let (kp_lsb_per_um, ki_lsb_per_um_s) = first_gains(t);
    Ok(Score {
        kp_lsb_per_um,
        ki_lsb_per_um_s,
        max_um,
        rms_um,
        faults: r
            .faults
            .iter()
            .map(|f| format!("{} at {:.3} s", f.name, f.t_s))
            .collect(),
    })
}

/// Kp and Ki of the set's first follower axis (by name; every axis is scaled alike).
fn first_gains(t: &Tuning) -> (f64, f64) {
    t.axes.values().next().map_or((0.0, 0.0), |g| {
        (f64::from(g.kp_lsb_per_um), f64::from(g.ki_lsb_per_um_s))
    })
}

/// A set the core refused: never chosen.
fn refused(t: &Tuning, e: &ScenarioError) -> Score {
    let (kp_lsb_per_um, ki_lsb_per_um_s) = first_gains(t);
    Score {
        kp_lsb_per_um,
        ki_lsb_per_um_s,
        max_um: f64::INFINITY,
        rms_um: f64::INFINITY,
        faults: vec![format!("refused: {e}")],
    }
}

/// The procedure for every (law, period) of `jobs` on scenario `s`; `done` is called
/// after each run with the number finished and the total.
pub fn compare(
    s: &Scenario,
    table: &CamCsv,
    jobs: &[(Controller, u32)],
    done: &(dyn Fn(usize, usize) + Sync),
) -> Result<Vec<Fair>, ScenarioError> {
    let s = followers_only(s);
    let rules = jobs
        .par_iter()
        .map(|&(c, p)| autotune::tune(&s, c, p, Margins::Nominal).map(|(t, _)| t))
        .collect::<Result<Vec<_>, _>>()?;
    let grid: Vec<(usize, f64, f64)> = (0..jobs.len())
        .flat_map(|j| {
            KP_FACTORS
                .iter()
                .flat_map(move |&fp| KI_FACTORS.iter().map(move |&fi| (j, fp, fi)))
        })
        .collect();
    let total = grid.len();
    let finished = std::sync::atomic::AtomicUsize::new(0);
    let scores = grid
        .par_iter()
        .map(|&(j, fp, fi)| {
            let t = rules.get(j).map(|r| scaled(r, fp, fi));
            let out = match t {
                // A set the core refuses (Ki·T beyond its format at a long period) is no
                // candidate; only the rule's own set must build.
                Some(t) => match score(&s, table, &t) {
                    Err(e) if fp != 1.0 || fi != 1.0 => Ok((j, fp, fi, refused(&t, &e))),
                    r => r.map(|sc| (j, fp, fi, sc)),
                },
                None => Err(ScenarioError::Invalid {
                    key: "fair".into(),
                    value: j.to_string(),
                    reason: "no rule set".into(),
                }),
            };
            let n = finished.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            done(n, total);
            out
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut out = Vec::new();
    for (j, (&(c, p), rule)) in jobs.iter().zip(&rules).enumerate() {
        let mine: Vec<&(usize, f64, f64, Score)> = scores.iter().filter(|x| x.0 == j).collect();
        let rule_score = mine
            .iter()
            .find(|x| x.1 == 1.0 && x.2 == 1.0)
            .map(|x| x.3.clone());
        let best = mine
            .iter()
            .filter(|x| x.3.faults.is_empty())
            .min_by(|a, b| {
                (a.3.max_um, a.3.rms_um)
                    .partial_cmp(&(b.3.max_um, b.3.rms_um))
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
            // Every run latched a fault: the rule's set, its faults shown.
            .or_else(|| mine.iter().find(|x| x.1 == 1.0 && x.2 == 1.0));
        if let (Some(rule_score), Some(best)) = (rule_score, best) {
            out.push(Fair {
                controller: c.name(),
                period_us: p,
                rule: rule_score,
                best: best.3.clone(),
                runs: mine.len(),
                tuning: scaled(rule, best.1, best.2),
            });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_never_exceeds_the_rules_gain_and_includes_it() {
        assert!(KP_FACTORS
            .iter()
            .all(|&f| f > 0.0 && f <= std::f64::consts::SQRT_2));
        assert!(KP_FACTORS.contains(&1.0) && KI_FACTORS.contains(&1.0));
        for w in KP_FACTORS.windows(2) {
            assert!((w[0] / w[1] - std::f64::consts::SQRT_2).abs() < 1e-9 || w[0] / w[1] == 2.0);
        }
        let mut t = Tuning {
            controller: Controller::Paper,
            period_us: 1000,
            master_filter_hz: 8.0,
            predictor: Default::default(),
            axes: Default::default(),
            press: Default::default(),
        };
        t.axes.insert(
            "a".into(),
            hydra_core::axis::PositionGains {
                kp_lsb_per_um: 1.0,
                ki_lsb_per_um_s: 16.0,
                ..Default::default()
            },
        );
        let g = scaled(&t, 0.5, 0.25).axes["a"];
        assert_eq!((g.kp_lsb_per_um, g.ki_lsb_per_um_s), (0.5, 1.0));
    }
}
