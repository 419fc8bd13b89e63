//! The board as the runtime sees it: the traits a real board (firmware) and a virtual
//! board (host simulator, tests) implement, so both run the same runtime.
//!
//! One tick through [`super::Runtime::tick_io`] calls, in this order:
//! 1. [`EncoderInput::latch`] — every encoder, as close to the period start as possible;
//! 2. [`SafetyInput::estop_active`];
//! 3. [`PressureInput::read`];
//! 4. the state machine and the control law;
//! 5. [`ValveOutput::write`] with every valve's code, then [`ValveOutput::set_enable`].

use crate::master::EdgeReading;
use crate::units::{Counts, DacCode, PressureBar};

/// Encoder counts latched together at the start of a period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EncoderSample<const S: usize> {
    /// Master encoder count (channel 0).
    pub master: Counts,
    /// Slave encoder counts (channels 1 … S).
    pub slaves: [Counts; S],
    /// The master encoder's edge timer read with the counts (`None`: the board has no
    /// edge timer; the master is then the count): the runtime estimates the master at the
    /// sample instant below one count from it ([`crate::master::EdgeEstimator`]).
    pub master_edges: Option<EdgeReading>,
}

/// Quadrature encoder inputs, already extended to 32 bits (see
/// [`super::encoder::Extender16`] for 16-bit counters).
pub trait EncoderInput<const S: usize> {
    /// Reads every channel, back to back.
    fn latch(&mut self) -> EncoderSample<S>;

    /// Per slave, the count latched in hardware at the last edge of its reference input
    /// or encoder index since the previous call (`None`: no edge). Read right after
    /// [`EncoderInput::latch`]; a board without reference inputs keeps the default.
    fn reference_edges(&mut self) -> [Option<Counts>; S] {
        [None; S]
    }
}

/// Per slave `k`, its chamber A and B pressures: the board's pressure inputs `2k` and
/// `2k + 1` (zero where the board has none).
#[inline]
pub fn chamber_pressures<const S: usize, const P: usize>(
    p: &[PressureBar; P],
) -> [[PressureBar; 2]; S] {
    let mut out = [[PressureBar::ZERO; 2]; S];
    for (k, pair) in out.iter_mut().enumerate() {
        for (j, v) in pair.iter_mut().enumerate() {
            if let Some(&bar) = p.get(k.saturating_mul(2).saturating_add(j)) {
                *v = bar;
            }
        }
    }
    out
}

/// Chamber pressure inputs.
pub trait PressureInput<const P: usize> {
    /// The latest pressures, bar (the board's own filtering applied).
    fn read(&mut self) -> [PressureBar; P];

    /// Whether the pressures are live: `false` when the converter has stopped updating
    /// (e.g. an ADC overrun stopped its DMA, until the board restarted it). Read after
    /// [`PressureInput::read`].
    fn healthy(&mut self) -> bool {
        true
    }
}

/// The E-stop input.
pub trait SafetyInput {
    /// `true` while the E-stop chain is open (stop requested, or the wire is broken).
    fn estop_active(&mut self) -> bool;
}

/// Valve outputs and the valve-power enable.
pub trait ValveOutput<const S: usize> {
    /// Writes every slave's valve code (`DacCode` 0 = DAC mid-scale).
    fn write(&mut self, codes: &[DacCode; S]);
    /// Switches the valve power (amplifier enable). `false` = valves unpowered.
    fn set_enable(&mut self, on: bool);
}

/// Everything a board provides to the runtime.
pub trait Board<const S: usize, const P: usize>:
    EncoderInput<S> + PressureInput<P> + SafetyInput + ValveOutput<S>
{
}

impl<T, const S: usize, const P: usize> Board<S, P> for T where
    T: EncoderInput<S> + PressureInput<P> + SafetyInput + ValveOutput<S>
{
}
