//! The valve-controller board: every pin, peripheral, DMA stream and interrupt priority
//! of the STM32F407VG (LQFP100) in one place. Another board or MCU = another file like
//! this one; the drivers (`valves`, `encoders`, `pressure`, `safety`, `link`) and the
//! runtime in `hydra-core` do not change.
//!
//! | function | pin(s) | peripheral | notes |
//! |---|---|---|---|
//! | valve 1 (slave 0) | PA4 | DAC1 ch 1 | 12-bit, output buffer on: swings 0.2 V … VDDA − 0.2 V; code 0 = 2048 = VDDA/2 = 1.500 V at VDDA = 3.0 V (`hydra_core::profile::VDDA_MV`); usable codes ±1774 ([`DAC_RANGE`]) |
//! | valve 2 (slave 1) | PA5 | DAC1 ch 2 | |
//! | master encoder A/B | PA0 / PA1 | TIM5 ch 1/2 (32-bit) | rotary table, 0.001°/count |
//! | slave 0 encoder A/B | PA15 / PB3 | TIM2 ch 1/2 (32-bit) | PA15/PB3 are JTDI/SWO: debug with SWD only |
//! | slave 1 encoder A/B | PB4 / PB5 | TIM3 ch 1/2 (16-bit, extended in software) | |
//! | slave 0 reference (index Z or switch) | PA2 | TIM2 ch 3, input capture | rising edge latches the count (`crate::encoders`); pull-down |
//! | slave 1 reference (index Z or switch) | PC8 | TIM3 ch 3, input capture | |
//! | pressure 0…3 | PC1 / PC2 / PB0 / PB1 | ADC1 IN11 / IN12 / IN8 / IN9, DMA2 stream 0 | continuous scan, 144-cycle samples |
//! | host link TX / RX | PC6 / PC7 | USART6 (AF8), DMA2 stream 6 / 1 (channel 5) | 921 600 8N1, +0.16 % (see [`LINK_BAUD`]); not USART1 on PA9, which the STM32F4-Discovery loads with its USB VBUS sense capacitor |
//! | table slots | — | flash sectors 10 / 11 (0x080C_0000 / 0x080E_0000) | `crate::flash` |
//! | valve-power enable | PE7 | GPIO push-pull out | high = valves powered; external pull-down |
//! | E-stop chain | PE8 | GPIO in, pull-down | high = chain closed (run permitted) |
//! | status LED | PD12 | GPIO out | green LED of the STM32F4-Discovery |
//! | master edge timer | — | TIM8 at 1 MHz, ch 1 captures TIM5's TRGO (ITR3) | every rising A edge of the master timestamped (`crate::edge_timer`) |
//! | tick timer | — | TIM7 update IRQ, priority 0 | hard period (1 kHz default) |
//! | time driver | — | TIM12 (embassy-time) | |
//! | watchdog | — | IWDG, 50 ms nominal (34–94 ms) | started first at reset, fed by the tick only (`crate::watchdog`) |
//!
//! Interrupt priorities (0 = most urgent): TIM7 tick 0; DMA 2; USART6 and the time
//! driver 3; thread-mode tasks (host link, status, LED) below every interrupt.

use embassy_stm32::adc::{Adc, AdcChannel, SampleTime};
use embassy_stm32::dac::Dac;
use embassy_stm32::gpio::{Input, Level, Output, Pull, Speed};
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::qei::{Qei, QeiMode};
use embassy_stm32::usart::{self, Uart};
use embassy_stm32::{bind_interrupts, dma, interrupt, pac, peripherals, Peri, Peripherals};
use hydra_core::runtime::{EncoderInput, EncoderSample, PressureInput, SafetyInput, ValveOutput};
use hydra_core::units::{Counts, DacCode, PressureBar};
use static_cell::StaticCell;

use crate::consts::{PRESSURES, SLAVES};
use crate::encoders::{Encoder16, Encoder32, Encoders};
use crate::pressure::{Pressures, ADC_BUF_LEN};
use crate::safety::EStop;
use crate::valves::{OnChipDac, ValveBank};

/// Host-link baud rate (the host tools' `host-sim … --port`: 921 600). USART6 on the
/// 84 MHz APB2 with 16× oversampling: USARTDIV = 84 MHz / (16 · 921 600) = 5.696 →
/// 5 + 11/16 = 5.6875, 923 077 Bd, +0.16 %. (On USART2 and the 42 MHz APB1 it would be
/// 2 + 14/16 = 2.875 → 913 043 Bd, −0.93 %: that is why the link moved, docs/firmware.md.)
pub const LINK_BAUD: u32 = 921_600;

/// The host link's actual baud rate: APB2 / (16 · USARTDIV), USARTDIV in 1/16 steps
/// rounded to nearest (RM0090 §30.3.4).
pub const fn link_baud_actual(pclk_hz: u32, baud: u32) -> u32 {
    // USARTDIV·16 = pclk / baud, rounded.
    let div16 = (pclk_hz + baud / 2) / baud;
    pclk_hz / div16
}

/// APB2 clock, Hz (USART6's kernel clock).
pub const APB2_HZ: u32 = 84_000_000;

// +0.16 %: within ±0.5 % (the host adapter's own error adds to it; 16× oversampling
// tolerates ≈ ±3.75 % in all).
const _: () = {
    let actual = link_baud_actual(APB2_HZ, LINK_BAUD);
    assert!(actual > LINK_BAUD && actual - LINK_BAUD < LINK_BAUD / 200);
};

bind_interrupts!(
    /// Interrupt bindings of the drivers.
    pub struct Irqs {
        USART6 => usart::InterruptHandler<peripherals::USART6>;
        DMA2_STREAM1 => dma::InterruptHandler<peripherals::DMA2_CH1>;
        DMA2_STREAM6 => dma::InterruptHandler<peripherals::DMA2_CH6>;
        DMA2_STREAM0 => dma::InterruptHandler<peripherals::DMA2_CH0>;
    }
);

/// Clock tree: 8 MHz HSE → PLL (÷4 ×168 ÷2) → 168 MHz SYSCLK; APB1 42 MHz (timers
/// 84 MHz), APB2 84 MHz (ADC clock 21 MHz); PLL Q 48 MHz.
pub fn hal_config() -> embassy_stm32::Config {
    use embassy_stm32::rcc::{
        AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv,
        PllSource, Sysclk,
    };
    let mut c = embassy_stm32::Config::default();
    c.rcc.hse = Some(Hse {
        freq: Hertz(8_000_000),
        mode: HseMode::Oscillator,
    });
    c.rcc.pll_src = PllSource::HSE;
    c.rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV4,
        mul: PllMul::MUL168,
        divp: Some(PllPDiv::DIV2),
        divq: Some(PllQDiv::DIV7),
        divr: None,
    });
    c.rcc.sys = Sysclk::PLL1_P;
    c.rcc.ahb_pre = AHBPrescaler::DIV1;
    c.rcc.apb1_pre = APBPrescaler::DIV4;
    c.rcc.apb2_pre = APBPrescaler::DIV2;
    // DMA completion interrupts must never delay the tick.
    c.dma_interrupt_priority = Priority::P2;
    c
}

/// The I/O the runtime drives every tick.
pub struct BoardIo {
    /// Encoders (latched first).
    pub encoders: Encoders<peripherals::TIM5, peripherals::TIM2, peripherals::TIM3>,
    /// Pressure inputs.
    pub pressures: Pressures,
    /// E-stop input.
    pub estop: EStop,
    /// Valve DACs and the valve-power enable.
    pub valves: ValveBank<SLAVES>,
}

impl EncoderInput<SLAVES> for BoardIo {
    #[inline]
    fn latch(&mut self) -> EncoderSample<SLAVES> {
        self.encoders.latch()
    }
    #[inline]
    fn reference_edges(&mut self) -> [Option<Counts>; SLAVES] {
        self.encoders.reference_edges()
    }
}

impl PressureInput<PRESSURES> for BoardIo {
    #[inline]
    fn read(&mut self) -> [PressureBar; PRESSURES] {
        self.pressures.read()
    }
    #[inline]
    fn healthy(&mut self) -> bool {
        self.pressures.healthy()
    }
}

impl SafetyInput for BoardIo {
    #[inline]
    fn estop_active(&mut self) -> bool {
        self.estop.estop_active()
    }
}

impl ValveOutput<SLAVES> for BoardIo {
    #[inline]
    fn write(&mut self, codes: &[DacCode; SLAVES]) {
        self.valves.write(codes);
    }
    #[inline]
    fn set_enable(&mut self, on: bool) {
        self.valves.set_enable(on);
    }
}

/// Everything `main` hands out after [`Board::new`].
pub struct Board {
    /// The tick's I/O.
    pub io: BoardIo,
    /// The host link UART (split by the link module).
    pub link: Uart<'static, embassy_stm32::mode::Async>,
    /// The tick timer.
    pub tick_timer: Peri<'static, peripherals::TIM7>,
    /// Status LED.
    pub led: Output<'static>,
    /// The internal flash (table slots in sectors 10 and 11).
    #[cfg_attr(feature = "console", allow(dead_code))]
    pub flash: embassy_stm32::flash::Flash<'static, embassy_stm32::flash::Blocking>,
}

static ADC_BUF: StaticCell<[u16; ADC_BUF_LEN]> = StaticCell::new();

impl Board {
    /// Brings the board up in the safe state: valve power off first, then the DAC at
    /// mid-scale (the caller writes the calibrated nulls at once), then the inputs.
    pub fn new(p: Peripherals) -> Self {
        // Valve power off before anything else can drive a valve.
        let enable = Output::new(p.PE7, Level::Low, Speed::Low);
        let dac = Dac::new_blocking(p.DAC1, p.PA4, p.PA5);
        let (ch1, ch2) = dac.split();
        let valves = ValveBank::new(
            [OnChipDac::new(ch1).into(), OnChipDac::new(ch2).into()],
            enable,
        );

        let qei_cfg = embassy_stm32::timer::qei::Config {
            ch1_pull: Pull::Up,
            ch2_pull: Pull::Up,
            mode: QeiMode::Mode3,
            auto_reload: u16::MAX,
        };
        let master = Encoder32::new(Qei::new(p.TIM5, p.PA0, p.PA1, qei_cfg), pac::TIM5);
        let slave0 = Encoder32::new(Qei::new(p.TIM2, p.PA15, p.PB3, qei_cfg), pac::TIM2);
        let slave1 = Encoder16::new(Qei::new(p.TIM3, p.PB4, p.PB5, qei_cfg), pac::TIM3);
        // After TIM5's encoder mode: its channel 1 capture and trigger output.
        let edges = crate::edge_timer::EdgeTimer::new(p.TIM8);
        let encoders = Encoders::new(master, slave0, slave1, edges);
        crate::encoders::reference_pins();

        let adc = Adc::new(p.ADC1);
        let buf = ADC_BUF.init([0; ADC_BUF_LEN]);
        let sequence = [
            (p.PC1.degrade_adc(), SampleTime::CYCLES144),
            (p.PC2.degrade_adc(), SampleTime::CYCLES144),
            (p.PB0.degrade_adc(), SampleTime::CYCLES144),
            (p.PB1.degrade_adc(), SampleTime::CYCLES144),
        ];
        let ring = adc.into_ring_buffered(
            p.DMA2_CH0,
            buf,
            Irqs,
            sequence.into_iter(),
            embassy_stm32::adc::CONTINUOUS,
            embassy_stm32::adc::Exten::DISABLED,
        );
        let pressures = Pressures::new(ring);

        let estop = EStop::new(Input::new(p.PE8, Pull::Down));

        let mut cfg = usart::Config::default();
        cfg.baudrate = LINK_BAUD;
        let link = Uart::new(p.USART6, p.PC7, p.PC6, p.DMA2_CH6, p.DMA2_CH1, Irqs, cfg)
            .unwrap_or_else(|_| defmt::panic!("USART6 configuration"));

        let led = Output::new(p.PD12, Level::Low, Speed::Low);

        // Everything the drivers enabled at the reset priority (0) goes below the tick.
        interrupt::USART6.set_priority(Priority::P3);
        interrupt::TIM8_BRK_TIM12.set_priority(Priority::P3);

        Self {
            io: BoardIo {
                encoders,
                pressures,
                estop,
                valves,
            },
            link,
            tick_timer: p.TIM7,
            led,
            flash: embassy_stm32::flash::Flash::new_blocking(p.FLASH),
        }
    }
}
