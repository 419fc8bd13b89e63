//! The bring-up console: a line protocol on the host link, for a terminal.
//!
//! Built with `--features console`, it takes the place of the framed protocol on the
//! link — it implements the same [`LinkProtocol`] trait — and the board answers plain
//! text lines (the link's baud rate, `crate::board::LINK_BAUD`, 8N1,
//! `\n` or `\r` terminated, case-insensitive):
//!
//! | line | effect | answer |
//! |---|---|---|
//! | `start` / `hold` / `stop` / `clear` | queues `Command::Start` / `Hold` / `Stop` / `ClearFault` for the next tick | `ok <cmd>` or `err <cmd> <reason>` once the tick has applied it |
//! | `status` | — | one `status …` line (the latest 10 ms snapshot) |
//! | `help` | — | the command list |
//!
//! and prints `event state=… fault=0x…` on every state change.

use core::fmt::Write;
use heapless::String;
use hydra_core::runtime::{Command, CommandError, State};

use crate::channels::{BoardStatus, Reply};
use crate::link::{LinkIo, LinkProtocol};

/// Longest accepted line.
const LINE_LEN: usize = 32;

/// The console's state: the line being received.
#[derive(Default)]
pub struct Console {
    line: String<LINE_LEN>,
    overflow: bool,
}

fn cmd_name(c: Command) -> &'static str {
    match c {
        Command::Start => "start",
        Command::Hold => "hold",
        Command::Stop => "stop",
        Command::ClearFault => "clear",
        Command::SetPosition { .. } => "set-position",
        Command::Home { .. } => "home",
        Command::Jog { .. } => "jog",
        Command::MoveTo { .. } => "move",
        Command::Approach { .. } => "approach",
        Command::Test { .. } => "test",
    }
}

fn state_name(s: State) -> &'static str {
    match s {
        State::Idle => "Idle",
        State::Following => "Following",
        State::Holding(hydra_core::runtime::HoldReason::Commanded) => "Holding",
        State::Holding(hydra_core::runtime::HoldReason::EndOfTable) => "HoldingAtEnd",
        State::Fault => "Fault",
        State::Manual => "Manual",
    }
}

fn error_text(e: CommandError, out: &mut String<96>) {
    let _ = match e {
        CommandError::NoController => write!(out, "no-program"),
        CommandError::Faulted => write!(out, "faulted"),
        CommandError::CauseActive(f) => write!(out, "cause-active 0x{:04x}", f.code()),
        CommandError::MasterMoved => write!(out, "master-moved"),
        CommandError::EndOfTable => write!(out, "end-of-table"),
        CommandError::Busy => write!(out, "busy"),
        CommandError::NotReferenced { axis } => write!(out, "not-referenced {}", axis),
        CommandError::NoAxis { axis } => write!(out, "no-axis {}", axis),
        CommandError::Motion { axis, .. } => write!(out, "motion-refused {}", axis),
    };
}

/// Writes one `status` line.
pub fn format_status(s: &BoardStatus, out: &mut String<512>) {
    let code = s.fault.map_or(0, |r| r.fault.code());
    let _ = write!(
        out,
        "status tick={} state={} fault=0x{:04x} set=0x{:04x} master={} pos_um={},{} target_um={},{} err_um={},{} dac={},{} en={} estop={} p_bar={:.1},{:.1},{:.1},{:.1} tick_cyc_max={} tick_cyc_mean={} overruns={}\r\n",
        s.tick,
        state_name(s.state),
        code,
        s.fault_set.0,
        s.master,
        s.pos_um[0],
        s.pos_um[1],
        s.target_um[0],
        s.target_um[1],
        s.error_um[0],
        s.error_um[1],
        s.dac[0].get(),
        s.dac[1].get(),
        u8::from(s.enable),
        u8::from(s.estop),
        s.pressure_bar[0],
        s.pressure_bar[1],
        s.pressure_bar[2],
        s.pressure_bar[3],
        s.timing.max_cycles,
        s.timing.mean_cycles,
        s.timing.overruns,
    );
}

impl Console {
    fn line_done(&mut self, io: &mut LinkIo<'_>) {
        let mut word: String<LINE_LEN> = String::new();
        for ch in self.line.trim().chars() {
            let _ = word.push(ch.to_ascii_lowercase());
        }
        self.line.clear();
        let cmd = match word.as_str() {
            "" => return,
            "start" => Some(Command::Start),
            "hold" => Some(Command::Hold),
            "stop" => Some(Command::Stop),
            "clear" => Some(Command::ClearFault),
            _ => None,
        };
        if let Some(c) = cmd {
            if !io.command(c) {
                io.send(b"err busy command-queue-full\r\n");
            }
            return;
        }
        match word.as_str() {
            "status" => {
                if let Some(s) = io.latest() {
                    let mut line: String<512> = String::new();
                    format_status(s, &mut line);
                    io.send(line.as_bytes());
                } else {
                    io.send(b"err status none-yet\r\n");
                }
            }
            "help" => {
                io.send(b"commands: start hold stop clear status help\r\n");
            }
            _ => {
                io.send(b"err unknown-command (help)\r\n");
            }
        }
    }
}

impl LinkProtocol for Console {
    fn on_rx(&mut self, bytes: &[u8], io: &mut LinkIo<'_>) {
        for &b in bytes {
            match b {
                b'\r' | b'\n' => {
                    if self.overflow {
                        self.overflow = false;
                        self.line.clear();
                        io.send(b"err line-too-long\r\n");
                    } else {
                        self.line_done(io);
                    }
                }
                _ if !b.is_ascii() || self.line.push(b as char).is_err() => self.overflow = true,
                _ => {}
            }
        }
    }

    fn on_reply(&mut self, reply: Reply, io: &mut LinkIo<'_>) {
        let mut line: String<96> = String::new();
        match reply.result {
            Ok(()) => {
                let _ = write!(line, "ok {}\r\n", cmd_name(reply.cmd));
            }
            Err(Some(e)) => {
                let _ = write!(line, "err {} ", cmd_name(reply.cmd));
                error_text(e, &mut line);
                let _ = line.push_str("\r\n");
            }
            Err(None) => {
                let _ = write!(line, "err {} expired\r\n", cmd_name(reply.cmd));
            }
        }
        io.send(line.as_bytes());
    }

    fn on_state_change(&mut self, s: &BoardStatus, io: &mut LinkIo<'_>) {
        let mut line: String<96> = String::new();
        let code = s.fault.map_or(0, |r| r.fault.code());
        let _ = write!(
            line,
            "event tick={} state={} fault=0x{:04x}\r\n",
            s.tick,
            state_name(s.state),
            code
        );
        io.send(line.as_bytes());
    }
}
