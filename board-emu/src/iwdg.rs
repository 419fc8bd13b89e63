//! The independent watchdog (RM0090 §21): started by 0xCCCC, fed by 0xAAAA, its prescaler
//! and reload writable after 0x5555; it counts down at the LSI clock / (4 · 2^PR) and
//! resets the board when it reaches zero.
//!
//! LSI: 32 kHz nominal (DS8626: 17–47 kHz); [`Iwdg::lsi_hz`] can be set to the ends of
//! that range. PR/RLR updates are busy (SR.PVU / RVU) for five LSI periods.

/// The watchdog.
#[derive(Debug, Clone)]
pub struct Iwdg {
    /// LSI frequency, Hz.
    pub lsi_hz: u64,
    unlocked: bool,
    pr: u32,
    rlr: u32,
    /// Core cycle at which the counter reaches zero (`None`: not started).
    pub deadline: Option<u64>,
    busy_until: u64,
    /// Feeds (0xAAAA writes) since reset.
    pub feeds: u64,
    /// The core cycles of the feeds (the last [`FEED_LOG`]).
    pub feed_log: std::collections::VecDeque<u64>,
}

/// Feeds remembered.
pub const FEED_LOG: usize = 4096;

impl Iwdg {
    /// At reset (not running).
    pub fn new() -> Self {
        Self {
            lsi_hz: 32_000,
            unlocked: false,
            pr: 0,
            rlr: 0xFFF,
            deadline: None,
            busy_until: 0,
            feeds: 0,
            feed_log: std::collections::VecDeque::new(),
        }
    }

    /// The timeout from a reload, in core cycles at `sysclk_hz`.
    pub fn timeout_cycles(&self, sysclk_hz: u64) -> u64 {
        let lsi_ticks = (u64::from(self.rlr) + 1) * (4u64 << self.pr.min(6));
        lsi_ticks * sysclk_hz / self.lsi_hz
    }

    /// A read.
    pub fn read(&self, off: u32, now: u64) -> Option<u32> {
        match off {
            0x00 => Some(0),
            0x04 => Some(self.pr),
            0x08 => Some(self.rlr),
            0x0C => Some(if now < self.busy_until { 3 } else { 0 }),
            _ => None,
        }
    }

    /// A write.
    pub fn write(&mut self, off: u32, v: u32, now: u64, sysclk_hz: u64) -> Option<()> {
        let busy = 5 * sysclk_hz / self.lsi_hz;
        match off {
            0x00 => match v & 0xFFFF {
                0xCCCC => {
                    if self.deadline.is_none() {
                        self.deadline = Some(now + self.timeout_cycles(sysclk_hz));
                    }
                }
                0xAAAA => {
                    if self.deadline.is_some() {
                        self.deadline = Some(now + self.timeout_cycles(sysclk_hz));
                    }
                    self.feeds += 1;
                    if self.feed_log.len() == FEED_LOG {
                        self.feed_log.pop_front();
                    }
                    self.feed_log.push_back(now);
                    self.unlocked = false;
                }
                0x5555 => self.unlocked = true,
                _ => self.unlocked = false,
            },
            0x04 => {
                if self.unlocked {
                    self.pr = v & 7;
                    self.busy_until = now + busy;
                }
            }
            0x08 => {
                if self.unlocked {
                    self.rlr = v & 0xFFF;
                    self.busy_until = now + busy;
                }
            }
            0x0C => {}
            _ => return None,
        }
        Some(())
    }
}

impl Default for Iwdg {
    fn default() -> Self {
        Self::new()
    }
}
