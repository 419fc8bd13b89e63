//! The host link: USART6 with DMA, served by one thread-mode task below every
//! interrupt, so it can never delay the tick.
//!
//! RX is a DMA ring buffer ([`RingBufferedUartRx`], [`RX_RING_LEN`] = 1024 bytes: 11 ms
//! of traffic at 921 600 Bd, two maximal frames) that keeps receiving while the task is
//! busy; TX is one DMA write per batch of output. The task wakes on received bytes or
//! every 10 ms, then:
//! 1. takes the tick's 10 ms status snapshots, logs state changes over defmt;
//! 2. feeds received bytes to the protocol ([`LinkProtocol::on_rx`]), which may queue
//!    commands for the tick (lock-free SPSC queue, applied at the next tick) and wait
//!    for their answers ([`LinkIo::command_wait`]);
//! 3. lets the protocol do deferred work ([`LinkProtocol::on_wake`]);
//! 4. hands the tick's remaining replies ([`LinkProtocol::on_reply`]), the state change
//!    ([`LinkProtocol::on_state_change`]) and every per-tick sample
//!    ([`LinkProtocol::on_sample`]) to the protocol;
//! 5. writes what the protocol queued for the host.
//!
//! The protocol is a trait ([`LinkProtocol`]): `main.rs` chooses the framed protocol
//! (`host_protocol::Framed`, default) or the bring-up text console (`console::Console`,
//! `--features console`) and spawns [`link_task`] with it.

use core::sync::atomic::{AtomicU8, Ordering};
use embassy_futures::select::{select, Either};
use embassy_stm32::mode::Async;
use embassy_stm32::usart::{RingBufferedUartRx, UartTx};
use embassy_time::{Duration, Instant, Timer};
use heapless::spsc::{Consumer, Producer};
use heapless::Vec;
use hydra_core::protocol::report::state_code;
use hydra_core::runtime::{Command, CommandError};

use crate::channels::{
    BoardStatus, LinkChannels, Reply, TickCommand, TickSample, COMMAND_WAIT_MS, REPLY,
};

/// Bytes the protocol may queue for the host per wake-up.
pub const OUT_LEN: usize = 2048;
/// RX DMA ring size.
pub const RX_RING_LEN: usize = 1024;

/// What a protocol handler can do on the link.
pub struct LinkIo<'a> {
    cmd_tx: &'a mut Producer<'static, TickCommand>,
    reply_rx: &'a mut Consumer<'static, Reply>,
    token: &'a mut u16,
    out: &'a mut Vec<u8, OUT_LEN>,
    latest: Option<&'a BoardStatus>,
}

impl LinkIo<'_> {
    fn queue(&mut self, c: Command) -> Option<u16> {
        *self.token = self.token.wrapping_add(1);
        let token = *self.token;
        let queued_at = cortex_m::peripheral::DWT::cycle_count();
        self.cmd_tx
            .enqueue(TickCommand {
                cmd: c,
                token,
                queued_at,
            })
            .ok()?;
        Some(token)
    }

    /// Queues a command for the next tick; `false` if the queue is full.
    #[cfg_attr(not(feature = "console"), allow(dead_code))]
    pub fn command(&mut self, c: Command) -> bool {
        self.queue(c).is_some()
    }

    /// Queues a command and waits for the tick's answer to *that* command (matched by
    /// token on the [`REPLY`] signal), at most [`COMMAND_WAIT_MS`] of embassy time. The
    /// wait sleeps (`WFE`) between interrupts: the tick's own interrupt, 1 ms later,
    /// wakes it with the answer. `None`: the queue was full or the tick did not answer
    /// in time — and then the command is never applied: the tick drops a command older
    /// than the wait (`crate::tick::COMMAND_MAX_AGE_US`).
    #[cfg_attr(feature = "console", allow(dead_code))]
    pub fn command_wait(&mut self, c: Command) -> Option<Result<(), CommandError>> {
        REPLY.reset();
        let token = self.queue(c)?;
        let deadline = Instant::now() + Duration::from_millis(u64::from(COMMAND_WAIT_MS));
        let answer = loop {
            if let Some(r) = REPLY.try_take() {
                if r.token == token {
                    break match r.result {
                        Ok(()) => Some(Ok(())),
                        Err(Some(e)) => Some(Err(e)),
                        Err(None) => None,
                    };
                }
            }
            if Instant::now() >= deadline {
                break None;
            }
            // Woken by any interrupt (the tick's every period, the time driver's).
            cortex_m::asm::wfe();
        };
        // The WFE may have consumed the event of a task woken meanwhile: the executor's
        // own WFE must not sleep through it.
        cortex_m::asm::sev();
        answer
    }

    /// Queues bytes only if all of them fit (a frame is never cut); returns whether
    /// they did.
    #[cfg_attr(feature = "console", allow(dead_code))]
    pub fn send_whole(&mut self, bytes: &[u8]) -> bool {
        self.out.extend_from_slice(bytes).is_ok()
    }

    #[cfg_attr(not(feature = "console"), allow(dead_code))]
    /// Queues bytes for the host (truncated if the batch is full; returns whether all fit).
    pub fn send(&mut self, bytes: &[u8]) -> bool {
        let room = OUT_LEN.saturating_sub(self.out.len());
        let n = bytes.len().min(room);
        let fit = self
            .out
            .extend_from_slice(bytes.get(..n).unwrap_or(&[]))
            .is_ok();
        fit && n == bytes.len()
    }

    /// The latest status snapshot (10 ms old at most once the tick runs).
    #[cfg_attr(not(feature = "console"), allow(dead_code))]
    pub fn latest(&self) -> Option<&BoardStatus> {
        self.latest
    }
}

/// A host-link protocol: the framed protocol (default) or the bring-up console
/// (`--features console`).
pub trait LinkProtocol {
    /// Bytes received from the host.
    fn on_rx(&mut self, bytes: &[u8], io: &mut LinkIo<'_>);
    /// The tick's answer to a queued command.
    fn on_reply(&mut self, reply: Reply, io: &mut LinkIo<'_>);
    /// The runtime changed state or latched a fault.
    fn on_state_change(&mut self, status: &BoardStatus, io: &mut LinkIo<'_>);
    /// Once per wake-up, after the received bytes (deferred work).
    fn on_wake(&mut self, _io: &mut LinkIo<'_>) {}
    /// One tick's sample, in tick order (samples the link was too slow for are lost).
    fn on_sample(&mut self, _sample: &TickSample, _io: &mut LinkIo<'_>) {}
}

/// The runtime state as a small code for the status LED (0 Idle, 1 Following,
/// 2 Holding, 3 Fault), published by the link task.
pub static STATE_CODE: AtomicU8 = AtomicU8::new(0);

/// The host-link task (see the module docs), with the protocol `main.rs` chose (one
/// task, not generic: the executor's task is a static, and a dynamic call per event costs
/// nothing next to a byte on the wire).
#[embassy_executor::task]
pub async fn link_task(
    mut rx: RingBufferedUartRx<'static>,
    mut tx: UartTx<'static, Async>,
    mut ch: LinkChannels,
    proto: &'static mut dyn LinkProtocol,
) {
    let mut buf = [0u8; 64];
    let mut out: Vec<u8, OUT_LEN> = Vec::new();
    let mut latest: Option<BoardStatus> = None;
    let mut token = 0u16;
    loop {
        let got = match select(rx.read(&mut buf), Timer::after_millis(10)).await {
            Either::First(Ok(n)) => n,
            Either::First(Err(e)) => {
                // Overrun/framing/noise: the ring restarts on the next read.
                defmt::warn!("host link rx error: {}", e);
                0
            }
            Either::Second(()) => 0,
        };
        let mut changed: Option<BoardStatus> = None;
        while let Some(s) = ch.status_rx.dequeue() {
            let prev = latest.map(|p| (p.state, p.fault));
            if prev != Some((s.state, s.fault)) {
                log_change(&s);
                changed = Some(s);
            }
            STATE_CODE.store(state_code(s.state), Ordering::Relaxed);
            latest = Some(s);
        }
        let mut io = LinkIo {
            cmd_tx: &mut ch.cmd_tx,
            reply_rx: &mut ch.reply_rx,
            token: &mut token,
            out: &mut out,
            latest: latest.as_ref(),
        };
        if let Some(bytes) = buf.get(..got) {
            if !bytes.is_empty() {
                proto.on_rx(bytes, &mut io);
            }
        }
        proto.on_wake(&mut io);
        while let Some(r) = io.reply_rx.dequeue() {
            defmt::info!("command {} -> {}", r.cmd, r.result);
            proto.on_reply(r, &mut io);
        }
        if let Some(s) = changed {
            proto.on_state_change(&s, &mut io);
        }
        while let Some(s) = ch.sample_rx.dequeue() {
            proto.on_sample(&s, &mut io);
        }
        if !out.is_empty() {
            if let Err(e) = tx.write(&out).await {
                defmt::warn!("host link tx error: {}", e);
            }
            out.clear();
        }
    }
}

fn log_change(s: &BoardStatus) {
    match s.fault {
        Some(r) => defmt::error!(
            "FAULT 0x{=u16:04x} {} at tick {}; state {}",
            r.fault.code(),
            r.fault,
            r.tick,
            s.state
        ),
        None => defmt::info!("state {} at tick {}", s.state, s.tick),
    }
}

/// The status LED: Idle blinks at 1 Hz, Following is on, Holding blinks at 2.5 Hz,
/// Fault at 5 Hz.
#[embassy_executor::task]
pub async fn led_task(mut led: embassy_stm32::gpio::Output<'static>) {
    let mut phase = 0u32;
    loop {
        let half_period_ticks = match STATE_CODE.load(Ordering::Relaxed) {
            0 => 10, // 50 ms ticks: 500 ms on/off
            1 => 0,
            2 => 2,
            _ => 1,
        };
        if half_period_ticks == 0 {
            led.set_high();
        } else if phase.is_multiple_of(half_period_ticks) {
            led.toggle();
        }
        phase = phase.wrapping_add(1);
        Timer::after_millis(50).await;
    }
}
