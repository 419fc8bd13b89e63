//! The gain backoff's thresholds in engineering units: what the settings tree holds for
//! each axis under `axis/<n>/backoff/…` beside the band (`axis/<n>/osc_band_um`), and
//! what a scenario's `[tuning.axes.<name>.backoff]` table sets. The defaults are the
//! detector as [`super`] describes it; [`super::BackoffCoeffs::build`] checks every
//! field against [`BackoffSettings::RANGES`] and converts it once for the control period.

/// The detector's and the cut's thresholds (the band itself is `osc_band_um`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(deny_unknown_fields, default)
)]
pub struct BackoffSettings {
    /// The high-pass corner f_hp that takes the slow tracking error out of the following
    /// error before it is counted, Hz (0.1 … 1 000; default 10).
    pub high_pass_hz: f32,
    /// Half-cycles across the band that make an oscillation, N (integer 2 … 16;
    /// default 4).
    pub half_cycles: f32,
    /// The window the N half-cycles must fall in, counted from the first, ms
    /// (1 … 10 000; default 150).
    pub window_ms: f32,
    /// After a cut, the time the raised band follows the oscillation up and nothing is
    /// counted, ms (0 … 10 000, at least one period; default 100).
    pub settle_ms: f32,
    /// The raised band's decay time constant back to the band, ms (1 … 100 000;
    /// default 500; applied as the nearest power-of-two number of periods).
    pub band_tau_ms: f32,
    /// The deepest level (integer 1 … [`super::MAX_LEVEL`]; default 4).
    pub max_level: f32,
    /// The proportional, derivative and damping scale at the first level, ratio
    /// (0.05 … 1; default 0.36).
    pub first_scale: f32,
    /// The scale's factor at each further level, ratio (0.05 … 1; default 0.75). The
    /// integrator step is scaled by min(1, step_scale^(level − 1)).
    pub step_scale: f32,
    /// The raised band after a cut and during the settling: this many times the
    /// oscillation's peak, ratio (1 … 4; default 1.25).
    pub band_margin: f32,
    /// The growth watch: a half-cycle grows when its peak exceeds the last one's on the
    /// same side by this fraction, ratio (0 … 1; default 0.0625 = 1/16).
    pub growth: f32,
    /// The growth watch: this many growing half-cycles in a row on one side take the
    /// next level (integer 1 … 16; default 3).
    pub growth_half_cycles: f32,
}

/// A backoff threshold out of range (the field it names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BackoffField {
    /// `high_pass_hz`.
    HighPassHz,
    /// `half_cycles`.
    HalfCycles,
    /// `window_ms`.
    WindowMs,
    /// `settle_ms`.
    SettleMs,
    /// `band_tau_ms`.
    BandTauMs,
    /// `max_level`.
    MaxLevel,
    /// `first_scale`.
    FirstScale,
    /// `step_scale`.
    StepScale,
    /// `band_margin`.
    BandMargin,
    /// `growth`.
    Growth,
    /// `growth_half_cycles`.
    GrowthHalfCycles,
}

impl BackoffField {
    /// Its key in a scenario's tuning table (`backoff.<field>`).
    pub const fn key(self) -> &'static str {
        match self {
            BackoffField::HighPassHz => "backoff.high_pass_hz",
            BackoffField::HalfCycles => "backoff.half_cycles",
            BackoffField::WindowMs => "backoff.window_ms",
            BackoffField::SettleMs => "backoff.settle_ms",
            BackoffField::BandTauMs => "backoff.band_tau_ms",
            BackoffField::MaxLevel => "backoff.max_level",
            BackoffField::FirstScale => "backoff.first_scale",
            BackoffField::StepScale => "backoff.step_scale",
            BackoffField::BandMargin => "backoff.band_margin",
            BackoffField::Growth => "backoff.growth",
            BackoffField::GrowthHalfCycles => "backoff.growth_half_cycles",
        }
    }
}

impl Default for BackoffSettings {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl BackoffSettings {
    /// The detector of [`super`]'s description.
    pub const DEFAULT: Self = Self {
        high_pass_hz: 10.0,
        half_cycles: 4.0,
        window_ms: 150.0,
        settle_ms: 100.0,
        band_tau_ms: 500.0,
        max_level: super::MAX_LEVEL as f32,
        first_scale: 0.36,
        step_scale: 0.75,
        band_margin: 1.25,
        growth: 0.0625,
        growth_half_cycles: 3.0,
    };

    /// Each field's accepted range (inclusive) and whether it must be an integer — the
    /// settings tree's ranges are these.
    pub const RANGES: [(BackoffField, f32, f32, bool); 11] = [
        (BackoffField::HighPassHz, 0.1, 1000.0, false),
        (BackoffField::HalfCycles, 2.0, 16.0, true),
        (BackoffField::WindowMs, 1.0, 10_000.0, false),
        (BackoffField::SettleMs, 0.0, 10_000.0, false),
        (BackoffField::BandTauMs, 1.0, 100_000.0, false),
        (BackoffField::MaxLevel, 1.0, super::MAX_LEVEL as f32, true),
        (BackoffField::FirstScale, 0.05, 1.0, false),
        (BackoffField::StepScale, 0.05, 1.0, false),
        (BackoffField::BandMargin, 1.0, 4.0, false),
        (BackoffField::Growth, 0.0, 1.0, false),
        (BackoffField::GrowthHalfCycles, 1.0, 16.0, true),
    ];

    /// The value of `field`.
    pub fn get(&self, field: BackoffField) -> f32 {
        match field {
            BackoffField::HighPassHz => self.high_pass_hz,
            BackoffField::HalfCycles => self.half_cycles,
            BackoffField::WindowMs => self.window_ms,
            BackoffField::SettleMs => self.settle_ms,
            BackoffField::BandTauMs => self.band_tau_ms,
            BackoffField::MaxLevel => self.max_level,
            BackoffField::FirstScale => self.first_scale,
            BackoffField::StepScale => self.step_scale,
            BackoffField::BandMargin => self.band_margin,
            BackoffField::Growth => self.growth,
            BackoffField::GrowthHalfCycles => self.growth_half_cycles,
        }
    }

    /// The field `field`, to write.
    pub fn get_mut(&mut self, field: BackoffField) -> &mut f32 {
        match field {
            BackoffField::HighPassHz => &mut self.high_pass_hz,
            BackoffField::HalfCycles => &mut self.half_cycles,
            BackoffField::WindowMs => &mut self.window_ms,
            BackoffField::SettleMs => &mut self.settle_ms,
            BackoffField::BandTauMs => &mut self.band_tau_ms,
            BackoffField::MaxLevel => &mut self.max_level,
            BackoffField::FirstScale => &mut self.first_scale,
            BackoffField::StepScale => &mut self.step_scale,
            BackoffField::BandMargin => &mut self.band_margin,
            BackoffField::Growth => &mut self.growth,
            BackoffField::GrowthHalfCycles => &mut self.growth_half_cycles,
        }
    }

    /// Checks every field: the first out of its range (or not finite, or not an integer
    /// where one is needed).
    pub fn check(&self) -> Result<(), BackoffField> {
        for (f, lo, hi, integer) in Self::RANGES {
            let v = self.get(f);
            if !(v.is_finite() && (lo..=hi).contains(&v)) || (integer && libm::truncf(v) != v) {
                return Err(f);
            }
        }
        Ok(())
    }
}
