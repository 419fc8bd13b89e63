//! Valve-controller firmware (STM32F407VG, 168 MHz): the hydra runtime on a board.
//!
//! The firmware is drivers and scheduling; states, fault rules and the control law are
//! `hydra-core`. Modules:
//! - [`board`]: the whole pin/peripheral/priority map and bring-up;
//! - [`valves`], [`encoders`], [`pressure`], [`safety`]: drivers behind the core's
//!   board traits;
//! - [`tick`]: the hard-period tick (TIM7 interrupt, priority 0);
//! - [`link`]: the host link (thread mode, below every interrupt) running [`framed`], the
//!   table-upload protocol of `PROTOCOL.md` over [`device`] (the runtime as the
//!   protocol's `Device`) and [`flash`] (tables in sectors 10/11) — or, built with
//!   `--features console`, the bring-up text [`console`];
//! - [`panic`]: panic/hard-fault handlers that null the valves first;
//! - [`program`]: the configuration the board boots with.
#![no_std]
#![no_main]

mod board;
mod boot_config;
mod capture;
mod channels;
#[cfg(feature = "console")]
mod console;
mod consts;
#[cfg(not(feature = "console"))]
mod device;
mod edge_timer;
mod encoders;
#[cfg(not(feature = "console"))]
mod flash;
mod flash_acr;
#[cfg(not(feature = "console"))]
mod host_protocol;
mod law_buffers;
mod link;
mod panic;
mod pressure;
mod safety;
mod tick;
mod valves;
mod watchdog;

use defmt_rtt as _;
use embassy_executor::Spawner;
use heapless::spsc::Queue;
#[cfg(feature = "console")]
use hydra_core::runtime::Runtime;
use static_cell::StaticCell;

use board::Board;
use channels::{BoardStatus, Reply, TickCommand, TickLinks, TickSample};
use tick::Tick;
use valves::ValveBank;

static CMD_Q: StaticCell<Queue<TickCommand, 8>> = StaticCell::new();
static REPLY_Q: StaticCell<Queue<Reply, 8>> = StaticCell::new();
static STATUS_Q: StaticCell<Queue<BoardStatus, 4>> = StaticCell::new();
/// Per-tick samples: 32 ticks of slack for the link task (it wakes at least every 10 ms).
static SAMPLE_Q: StaticCell<Queue<TickSample, 32>> = StaticCell::new();
#[cfg(not(feature = "console"))]
static FRAMED: StaticCell<host_protocol::Framed> = StaticCell::new();
static RX_RING: StaticCell<[u8; link::RX_RING_LEN]> = StaticCell::new();

#[cfg(feature = "console")]
static CONSOLE: StaticCell<console::Console> = StaticCell::new();

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // The watchdog first: every later step (the HSE wait has no timeout) is covered.
    watchdog::start(watchdog::Timeout::BOOT);
    let boot = panic::boot_cause();
    let p = embassy_stm32::init(board::hal_config());
    // embassy sets only the wait states: prefetch and caches on (RM0090 §3.5.2).
    flash_acr::enable_accelerator();
    let mut board = Board::new(p);

    let coeffs = match boot_config::runtime_coeffs() {
        Ok(c) => c,
        Err(e) => defmt::panic!("runtime configuration rejected: {}", e),
    };
    // The framed protocol and the runtime with the boot law from the newest valid flash
    // slot (built in place in a law buffer) and the reference offsets saved with it.
    #[cfg(not(feature = "console"))]
    let (proto, rt) = {
        let flash = flash::SlotFlash::new(board.flash);
        // `Framed` itself is small (its tables are statics): moved once into its cell.
        let fr = match host_protocol::Framed::new(flash) {
            Ok(f) => FRAMED.init(f),
            Err(e) => defmt::panic!("table slots: {}", e),
        };
        match fr.boot() {
            Some(h) if h.rows == 0 => defmt::info!(
                "settings without a table from slot {=u8}, generation {=u32}",
                h.slot,
                h.generation
            ),
            Some(h) => defmt::info!(
                "table {=u32} ({=u16} rows) from slot {=u8}, generation {=u32}",
                h.id,
                h.rows,
                h.slot,
                h.generation
            ),
            None => defmt::warn!("no valid table in flash: idle without a law"),
        }
        let (rt, refused) = fr.dev.start(coeffs, boot);
        if refused != 0 {
            defmt::warn!("persisted offsets not restored (slaves {=u32:b})", refused);
        }
        (fr, rt)
    };
    #[cfg(feature = "console")]
    let (proto, rt) = match boot_config::boot_law() {
        Ok(l) => (
            console::Console::default(),
            Runtime::new(coeffs, Some(l), boot),
        ),
        Err(e) => {
            defmt::error!("boot program rejected: {}; running without a law", e);
            (
                console::Console::default(),
                Runtime::new(coeffs, None, boot),
            )
        }
    };
    // The boot law's valve nulls first: the DAC leaves mid-scale for the calibrated null
    // before the tick runs.
    if rt.law().is_some() {
        let n = rt.null_codes();
        ValveBank::publish_safe_codes(&n);
        board.io.valves.write(&n);
    }
    defmt::info!(
        "hydra firmware: boot {}, period {} us, state {}, flash prefetch+caches {}",
        boot,
        coeffs.period_us,
        rt.state(),
        flash_acr::accelerator_on()
    );

    if let Some(mut cp) = cortex_m::Peripherals::take() {
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
    } else {
        defmt::warn!("core peripherals already taken: tick cycle counts will read 0");
    }
    panic::freeze_in_debug();

    let (cmd_tx, cmd_rx) = CMD_Q.init(Queue::new()).split();
    let (reply_tx, reply_rx) = REPLY_Q.init(Queue::new()).split();
    let (status_tx, status_rx) = STATUS_Q.init(Queue::new()).split();
    let (sample_tx, sample_rx) = SAMPLE_Q.init(Queue::new()).split();

    let Board {
        io,
        link,
        tick_timer,
        led,
        ..
    } = board;
    tick::start(Tick::new(
        rt,
        io,
        tick_timer,
        TickLinks {
            cmd_rx,
            reply_tx,
            status_tx,
            sample_tx,
            capture: match capture::take() {
                Some(c) => c,
                None => defmt::panic!("capture ring taken twice"),
            },
        },
    ));

    let (tx, rx) = link.split();
    let rx = rx.into_ring_buffered(RX_RING.init([0; link::RX_RING_LEN]));
    let channels = channels::LinkChannels {
        cmd_tx,
        reply_rx,
        status_rx,
        sample_rx,
    };
    // The protocol the link runs: chosen here, the link task knows only its trait.
    #[cfg(not(feature = "console"))]
    let proto: &'static mut dyn link::LinkProtocol = proto;
    #[cfg(feature = "console")]
    let proto: &'static mut dyn link::LinkProtocol = CONSOLE.init(proto);
    match link::link_task(rx, tx, channels, proto) {
        Ok(t) => spawner.spawn(t),
        Err(e) => defmt::panic!("spawn link: {}", e),
    }
    match link::led_task(led) {
        Ok(t) => spawner.spawn(t),
        Err(e) => defmt::panic!("spawn led: {}", e),
    }
}
