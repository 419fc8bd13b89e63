//! The controller's view of the plant: quantised sensors and the valve DAC.
//!
//! * Linear encoder: `n = round(x / r)`, `r` = 1 µm per count by default. Rounding (not
//!   truncation) is the quantiser of an encoder whose reference mark sits half a count
//!   off the origin: the reading is unbiased, its error within ±r/2.
//! * Master (rotary-table) encoder: `n = round(θ / r_θ)`, `r_θ` = 0.001° per count.
//! * Pressure transducer + ADC: `code = clamp(round(p/p_fs · (2^bits − 1)), 0, 2^bits − 1)`,
//!   reading `code · p_fs / (2^bits − 1)`; 0–250 bar through 12 bits is 0.061 bar per LSB.
//! * Valve DAC: signed code `n ∈ [−2047, 2047]` → `u = n / 2047`.

use hydra_core::units::DacCode;

/// A linear quantiser `n = round(value / resolution)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Encoder {
    /// Value of one count (m for a linear encoder, degrees for the master).
    pub resolution: f64,
}

impl Encoder {
    /// The count for a value (saturated to the `i64` range).
    #[inline]
    pub fn count(&self, value: f64) -> i64 {
        (value / self.resolution).round() as i64
    }

    /// The value a count stands for.
    #[inline]
    pub fn value(&self, count: i64) -> f64 {
        count as f64 * self.resolution
    }
}

/// A pressure transducer of full scale `p_fs` read through a unipolar ADC.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PressureAdc {
    /// Full-scale pressure, Pa (PLANT.md: 250 bar).
    pub full_scale_pa: f64,
    /// ADC resolution, bits (PLANT.md: 12).
    pub bits: u32,
}

impl PressureAdc {
    fn max_code(&self) -> f64 {
        f64::from((1u32 << self.bits) - 1)
    }

    /// The ADC code for a pressure, `[0, 2^bits − 1]`.
    #[inline]
    pub fn code(&self, p_pa: f64) -> u32 {
        (p_pa / self.full_scale_pa * self.max_code())
            .round()
            .clamp(0.0, self.max_code()) as u32
    }

    /// The pressure a code stands for, Pa.
    #[inline]
    pub fn pressure_pa(&self, code: u32) -> f64 {
        f64::from(code) * self.full_scale_pa / self.max_code()
    }

    /// The quantised reading of a pressure, Pa.
    #[inline]
    pub fn read_pa(&self, p_pa: f64) -> f64 {
        self.pressure_pa(self.code(p_pa))
    }
}

/// The normalised valve command of a signed DAC code (0 = mid-scale, ±2047 = full
/// scale) with the valve power on, `u = n/2047` clamped to [−1, 1]; 0 with it off (the
/// spool centres). The one conversion from DAC code to valve opening: the simulated
/// runs, the virtual board and board-emu all drive the plant's valves through it.
#[inline]
pub fn valve_command(code: i16, enable: bool) -> f64 {
    if enable {
        (f64::from(code) / f64::from(DacCode::MAX)).clamp(-1.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoder_rounds() {
        let e = Encoder { resolution: 1e-6 };
        assert_eq!(e.count(0.2494996), 249_500);
        assert_eq!(e.count(-1.4e-6), -1);
        assert!((e.value(249_500) - 0.2495).abs() < 1e-12);
        let m = Encoder { resolution: 1e-3 };
        assert_eq!(m.count(90.0), 90_000);
    }

    #[test]
    fn pressure_adc_quantises_and_clamps() {
        let a = PressureAdc {
            full_scale_pa: 250e5,
            bits: 12,
        };
        assert_eq!(a.code(0.0), 0);
        assert_eq!(a.code(-5e5), 0);
        assert_eq!(a.code(300e5), 4095);
        let lsb = 250e5 / 4095.0;
        for p in [1e5, 80e5, 159.9e5] {
            assert!((a.read_pa(p) - p).abs() <= 0.5 * lsb + 1e-6);
        }
    }

    #[test]
    fn dac_maps_to_unit() {
        assert_eq!(valve_command(DacCode::new_clamped(2047).get(), true), 1.0);
        assert_eq!(valve_command(DacCode::new_clamped(-2047).get(), true), -1.0);
        assert_eq!(valve_command(DacCode::NULL.get(), true), 0.0);
        assert_eq!(valve_command(2047, false), 0.0);
        assert_eq!(valve_command(i16::MAX, true), 1.0);
        assert!((valve_command(1024, true) - 0.5002).abs() < 1e-3);
    }
}
