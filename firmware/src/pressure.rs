//! Pressure inputs: ADC1 scanning four channels continuously into a circular DMA
//! buffer; the tick averages the newest complete scans.
//!
//! At 21 MHz ADC clock and 144 + 12 cycles per conversion a scan of four channels takes
//! 29.7 µs (33.6 kHz per channel). Each tick reads up to [`AVG_SCANS`] of the newest scans
//! (a ≤ 238 µs moving average: an anti-alias filter well above the transducers'
//! bandwidth) and keeps the previous value if no new scan arrived (at 10 kHz ticks
//! about 3 scans arrive per tick). The average is kept in 1/16 LSB and scaled to bar by
//! `hydra_core::runtime::pressure::PressureScale`.
//!
//! **Overrun.** If the DMA ever misses a conversion (ADC_SR.OVR), the F4's ADC stops
//! issuing DMA requests (RM0090 §13.8.1) and the pressures would freeze silently. Each
//! read checks the flag and, if set, re-initialises the chain (`Pressures::restart`: the
//! DMA stream stopped and reprogrammed, the ADC off and on with its overrun flag cleared,
//! then both restarted). Independently, no new scan for [`STALE_US`] makes the input unhealthy
//! (`PressureInput::healthy`): reported in Status, and a fault when a force axis depends
//! on the pressures (`RuntimeConfig::pressure_required`).

use embassy_stm32::adc::RingBufferedAdc;
use embassy_stm32::pac;
use embassy_stm32::peripherals::ADC1;
use hydra_core::runtime::pressure::{PressureCal, PressureScale};
use hydra_core::units::PressureBar;

use crate::consts::PRESSURES;

/// Scans averaged per tick (at most).
pub const AVG_SCANS: usize = 8;
/// DMA ring length: 64 scans of four channels.
pub const ADC_BUF_LEN: usize = PRESSURES * 64;
/// No new scan for this long (µs; ≈ 67 scan periods) makes the input stale.
pub const STALE_US: u32 = 2000;
/// [`STALE_US`] in ticks (at least 1).
const STALE_TICKS: u32 = {
    let t = STALE_US / crate::consts::PERIOD_US;
    if t == 0 {
        1
    } else {
        t
    }
};

/// The pressure inputs.
pub struct Pressures {
    ring: RingBufferedAdc<'static, ADC1>,
    scale: [PressureScale; PRESSURES],
    last: [PressureBar; PRESSURES],
    scratch: [u16; PRESSURES * AVG_SCANS],
    /// Ticks since the last new scan.
    stale_ticks: u32,
}

impl Pressures {
    /// Starts continuous conversion; every channel scaled 0–250 bar over the ADC's full
    /// scale (the reference transducers, PLANT.md).
    pub fn new(mut ring: RingBufferedAdc<'static, ADC1>) -> Self {
        ring.start();
        let default = PressureCal::default()
            .build()
            .unwrap_or_else(|_| defmt::panic!("default pressure calibration"));
        Self {
            ring,
            scale: [default; PRESSURES],
            last: [PressureBar::ZERO; PRESSURES],
            scratch: [0; PRESSURES * AVG_SCANS],
            stale_ticks: 0,
        }
    }

    /// The newest averaged pressures (the previous ones if no scan completed).
    #[inline]
    pub fn read(&mut self) -> [PressureBar; PRESSURES] {
        if pac::ADC1.sr().read().ovr() {
            self.restart();
        }
        let n = self.ring.read_latest(&mut self.scratch);
        let scans = n / PRESSURES;
        self.stale_ticks = if scans > 0 {
            0
        } else {
            self.stale_ticks.saturating_add(1)
        };
        if scans > 0 {
            let mut sum = [0u32; PRESSURES];
            for scan in self.scratch.chunks_exact(PRESSURES).take(scans) {
                for (s, &v) in sum.iter_mut().zip(scan.iter()) {
                    *s += u32::from(v);
                }
            }
            for ((p, s), k) in self.last.iter_mut().zip(sum.iter()).zip(self.scale.iter()) {
                // Mean in 1/16 LSB: 16·Σ/n ≤ 16·4095 (n ≥ 1).
                *p = k.bar(s * 16 / scans as u32);
            }
        }
        self.last
    }

    /// Whether a scan arrived within [`STALE_US`].
    #[inline]
    pub fn healthy(&self) -> bool {
        self.stale_ticks < STALE_TICKS
    }

    /// Restarts conversions and DMA after an overrun (RM0090 §13.8.1: "re-initialise
    /// both the DMA and the ADC"). A stream disabled mid-transfer keeps its NDTR and would
    /// restart from the buffer's start with the old count — the channels rotated for good —
    /// so the stream is stopped and *reprogrammed* (§10.3.14): pause, wait until EN reads
    /// 0 (bounded), NDTR = the whole ring, stream 0's flags cleared; the ADC off and on,
    /// OVR cleared, its DMA requests off and on; then the ring re-synchronised and both
    /// restarted.
    #[cold]
    fn restart(&mut self) {
        self.ring.stop();
        let st = pac::DMA2.st(0);
        // EN reads 0 once the current transfer has finished (a few bus cycles).
        for _ in 0..10_000u32 {
            if !st.cr().read().en() {
                break;
            }
        }
        st.ndtr().write(|w| w.set_ndt(ADC_BUF_LEN as u16));
        pac::DMA2.ifcr(0).write(|w| {
            w.set_tcif(0, true);
            w.set_htif(0, true);
            w.set_teif(0, true);
            w.set_dmeif(0, true);
            w.set_feif(0, true);
        });
        let adc = pac::ADC1;
        adc.cr2().modify(|w| {
            w.set_dma(false);
            w.set_adon(false);
        });
        // OVR is cleared by writing 0.
        adc.sr().modify(|w| w.set_ovr(false));
        adc.cr2().modify(|w| w.set_adon(true));
        adc.cr2().modify(|w| w.set_dma(true));
        self.ring.clear();
        self.ring.start();
    }
}
