//! S-curve figures (SPEC §B): the per-period sample of a planned 7-phase move.
//!
//! Set-up: an X–Y line from (0, 0) to (100 mm, 50 mm) at path limits V = 50 mm/s,
//! A = 500 mm/s², J = 10 000 mm/s³, period 1 ms: all seven phases (both A and V
//! reached), 2 300 periods long. The leader (X) moves 100 mm = 25.6·10⁶ LSB of `PosUm`.
//!
//! * `scurve_sample`: [`Profile::position_at`] (the closed form of the current phase,
//!   the per-period evaluation) at ticks cycling through the whole move, so the figure
//!   is the average over every phase.
//! * `scurve_line_xy`: [`LineMove::next`] for the two axes (the profile sample through
//!   the monotone cursor, then one product per axis), the move restarted when done.

use crate::harness::Figure;
use core::hint::black_box;
use hydra_core::scurve::{Cursor, LineMove, PathLimits, Profile};
use hydra_core::units::PosUm;

/// Control period, s.
const PERIOD_S: f64 = 0.001;

/// The reference X–Y line move.
fn line() -> Option<LineMove<2>> {
    LineMove::plan(
        [PosUm::ZERO, PosUm::ZERO],
        [PosUm::from_num(100_000), PosUm::from_num(50_000)],
        &PathLimits {
            vel_um_per_s: 50_000.0,
            acc_um_per_s2: 500_000.0,
            jerk_um_per_s3: 10_000_000.0,
        },
        PERIOD_S,
    )
    .ok()
}

/// The measured call: one profile sample.
#[inline(never)]
fn position_at(p: &Profile, k: u32) -> i64 {
    p.position_at(k)
}

/// `scurve_sample`.
pub struct ProfileSample {
    profile: Profile,
    period: u32,
    out: i64,
}

impl ProfileSample {
    /// The leader's profile of the reference line.
    pub fn new() -> Option<Self> {
        let profile = *line()?.profile();
        let period = profile.end_tick().checked_add(1)?;
        Some(Self {
            profile,
            period,
            out: 0,
        })
    }
}

impl Figure for ProfileSample {
    #[inline(always)]
    fn call(&mut self, k: u32) {
        self.out = position_at(&self.profile, k % self.period);
    }

    #[inline(always)]
    fn baseline(&mut self, k: u32) {
        black_box(k % self.period);
        black_box(&mut self.out);
    }

    fn healthy(&self) -> bool {
        (0..=self.profile.distance_lsb()).contains(&self.out)
    }
}

/// The measured call: the next X–Y sample of the line.
#[inline(never)]
fn line_next(l: &LineMove<2>, c: &mut Cursor) -> [PosUm; 2] {
    l.next(c)
}

/// `scurve_line_xy`.
pub struct LineXy {
    line: LineMove<2>,
    cursor: Cursor,
    out: [PosUm; 2],
}

impl LineXy {
    /// The reference line, cursor at tick 0.
    pub fn new() -> Option<Self> {
        Some(Self {
            line: line()?,
            cursor: Cursor::new(),
            out: [PosUm::ZERO; 2],
        })
    }

    #[inline(always)]
    fn restart_when_done(&mut self) {
        if self.cursor.done(self.line.profile()) {
            self.cursor = Cursor::new();
        }
    }
}

impl Figure for LineXy {
    #[inline(always)]
    fn call(&mut self, _k: u32) {
        self.restart_when_done();
        self.out = line_next(&self.line, &mut self.cursor);
    }

    #[inline(always)]
    fn baseline(&mut self, _k: u32) {
        self.restart_when_done();
        black_box(&mut self.cursor);
        black_box(&mut self.out);
    }

    fn healthy(&self) -> bool {
        let [x, y] = self.out;
        x >= PosUm::ZERO && y >= PosUm::ZERO && x <= self.line.to()[0] && y <= self.line.to()[1]
    }
}
