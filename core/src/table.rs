//! The cam table: slave positions as single-valued functions of the master (SPEC §A).
//!
//! Nodes (θ_j, x_j) with θ strictly increasing (a decreasing master column is reversed
//! when the table is built). Between nodes each slave is interpolated linearly (eq. 5):
//!
//! ```text
//! x*(θ) = x_j + (x_{j+1} − x_j) · (θ − θ_j) / (θ_{j+1} − θ_j),   θ_j ≤ θ < θ_{j+1}
//! ```
//!
//! Everything that does not depend on θ is computed once when the table is built: per
//! segment the start (θ_j, x_j), the rise Δx_j and the reciprocal of the segment length
//! `recip_j = ⌈2^64 / len_j⌉` (len_j in raw `I48F16` bits). Per tick the fraction is
//! then one multiplication, `frac = (θ − θ_j)·recip_j >> 32` (Q0.32, never below the exact fraction and above it by less than 2^-32), and
//! each slave one more, `x = x_j + Δx_j·frac >> 32`: no division in the control loop.
//! Segment search starts from the segment of the previous call (the cursor) and walks
//! one node at a time, so it is O(1) amortised for a master moving either way.
//!
//! Limits: 2 ≤ nodes ≤ N; segment length 2^-15 … 65 535 master counts (so θ − θ_j fits a
//! `u32` of raw bits); slave values within the axis' range; each slave's slope within
//! its axis' speed limit at the stated master speed: |Δx_j|·θ̇_max ≤ v_max·len_j.

use crate::fixed_point::sat_i32;
use crate::units::{Master, MasterRate, PosUm, VelUmPerS};
use heapless::Vec;

/// A table node: the master value and every slave's position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Node<const S: usize> {
    /// Master value, master counts.
    pub master: Master,
    /// Slave positions, µm.
    pub slave_um: [PosUm; S],
}

/// Per-slave validation limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AxisLimits {
    /// Smallest position the axis may be commanded to, µm.
    pub min_um: PosUm,
    /// Largest position the axis may be commanded to, µm.
    pub max_um: PosUm,
    /// Largest speed the axis can give, µm/s.
    pub max_speed_um_per_s: VelUmPerS,
}

/// Validation limits of a table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TableLimits<const S: usize> {
    /// The fastest master speed the table will be run at, master counts/s (> 0).
    pub master_speed_per_s: MasterRate,
    /// Per-slave limits.
    pub axes: [AxisLimits; S],
}

/// Why a table was rejected. `row` is the 0-based index of the node in the order given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TableError {
    /// Fewer than two nodes.
    TooFewNodes,
    /// More nodes than the table's capacity.
    TooManyNodes {
        /// The capacity.
        capacity: usize,
    },
    /// The master column is not strictly monotonic at this row.
    NotMonotonic {
        /// Row index.
        row: usize,
    },
    /// The segment ending at this row is longer than 65 535 or shorter than 2^-15 counts.
    SegmentLength {
        /// Row index.
        row: usize,
    },
    /// A slave value outside its axis' range.
    OutOfRange {
        /// Row index.
        row: usize,
        /// Slave column (0-based).
        axis: usize,
    },
    /// The segment ending at this row asks for more speed than the axis can give.
    TooSteep {
        /// Row index.
        row: usize,
        /// Slave column (0-based).
        axis: usize,
    },
    /// The stated master speed is not positive.
    MasterSpeed,
}

impl core::fmt::Display for TableError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::TooFewNodes => write!(f, "a table needs at least 2 nodes"),
            Self::TooManyNodes { capacity } => write!(f, "more than {capacity} nodes"),
            Self::NotMonotonic { row } => {
                write!(f, "row {row}: master column not strictly monotonic")
            }
            Self::SegmentLength { row } => write!(
                f,
                "row {row}: segment length outside 2^-15 .. 65535 master counts"
            ),
            Self::OutOfRange { row, axis } => {
                write!(f, "row {row}: slave {axis} outside its axis range")
            }
            Self::TooSteep { row, axis } => write!(
                f,
                "row {row}: slave {axis} slope exceeds the axis speed limit at the stated master speed"
            ),
            Self::MasterSpeed => write!(f, "the stated master speed must be positive"),
        }
    }
}

impl core::error::Error for TableError {}

/// One segment, precomputed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Segment<const S: usize> {
    /// θ_j, raw `I48F16`.
    m0: i64,
    /// len_j = θ_{j+1} − θ_j, raw `I48F16` bits (2 … 2^32 − 2^16).
    len: u32,
    /// ⌈2^64 / len_j⌉, len_j in raw bits (≥ 2).
    recip: u64,
    /// 2^24 / len_j ≈ recip_m · 2^-recip_s with recip_m ∈ [2^31, 2^32) (a 32-bit
    /// floating reciprocal for rates: master speed / segment length).
    recip_m: u32,
    /// See `recip_m` (8 … 40; 32 and more for segments of 256 counts and longer).
    recip_s: u32,
    /// x_j, raw `I24F8` µm.
    x0: [i32; S],
    /// x_{j+1} − x_j, raw `I24F8` µm (|Δx| < 2^31 since both ends are in range).
    dx: [i32; S],
}

impl<const S: usize> Segment<S> {
    /// θ − θ_j for a master θ (raw `I48F16`) inside this segment, `None` outside: the
    /// difference modulo 2^64 (the master's own arithmetic, see
    /// [`crate::master::MasterFilter::update`]) is in [0, len_j) exactly when θ is in the
    /// segment (a table spans far less than 2^63 raw), and then below 2^32.
    #[inline(always)]
    fn offset(&self, m: i64) -> Option<u32> {
        let d = m.wrapping_sub(self.m0) as u64;
        if d < u64::from(self.len) {
            Some(d as u32)
        } else {
            None
        }
    }

    /// `rate / len` in segments per unit time, Q16.16, for a rate in master counts per
    /// unit time, Q24.8 (see [`CamTable::seg_rate_q16`]).
    #[inline(always)]
    fn rate_q16(&self, rate_q8: i32) -> i32 {
        // rate[Q8]·2^24/len[Q16] = rate/len·2^16; |rate|·recip_m < 2^63.
        let p = i64::from(rate_q8).wrapping_mul(i64::from(self.recip_m));
        if self.recip_s >= 32 {
            // Segments of 2^24 raw bits (256 counts) and longer: the high word shifted
            // by 0 … 7 (a 32-bit shift, and the result cannot overflow).
            ((p >> 32) as i32).wrapping_shr(self.recip_s.wrapping_sub(32))
        } else {
            sat_i32(p.wrapping_shr(self.recip_s))
        }
    }
}

/// Where a master value falls in the table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Lookup {
    /// Segment index.
    pub seg: usize,
    /// Fraction through the segment, Q0.32.
    pub frac_q32: u32,
    /// Which end the master is beyond, if any (the value is then clamped to that end).
    pub beyond: Beyond,
}

/// Whether a master value is beyond an end of the table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Beyond {
    /// Inside [θ_first, θ_last).
    #[default]
    Inside,
    /// Below the first node.
    Low,
    /// At or above the last node.
    High,
}

/// A validated cam table of up to `N` nodes and `S` slave columns.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CamTable<const S: usize, const N: usize> {
    segs: Vec<Segment<S>, N>,
    last: Node<S>,
}

/// Longest segment between two nodes, master counts (the table's rule; Info reports it).
pub const MAX_SEGMENT_COUNTS: u32 = 65_535;
/// Largest segment length, raw bits (65 535 counts · 2^16 < 2^32).
const MAX_LEN_BITS: i64 = (MAX_SEGMENT_COUNTS as i64) << 16;

/// Checks `nodes` against every rule a table of `capacity` rows obeys (the rules of
/// [`CamTable::rebuild_from_nodes`], which a board applies at commit), building nothing:
/// a host checks a table before uploading it with the limits, capacity and longest
/// segment (at most [`MAX_SEGMENT_COUNTS`]) the board reported. Rows in the errors are
/// indices into `nodes`.
pub fn check_nodes<const S: usize>(
    nodes: &[Node<S>],
    limits: &TableLimits<S>,
    capacity: usize,
    max_segment_counts: u32,
) -> Result<(), TableError> {
    let max_len = (i64::from(max_segment_counts) << 16).min(MAX_LEN_BITS);
    build_segments(nodes, limits, capacity, max_len, |_| Ok(())).map(|_| ())
}

impl<const S: usize, const N: usize> CamTable<S, N> {
    /// An empty table (no segment): the starting value of a table buffer that is filled
    /// in place by [`Self::rebuild_from_nodes`] or [`Self::copy_from`]. `const`, so a
    /// static buffer is initialised at link time, never through the stack. An empty
    /// table is not a valid cam table ([`Self::is_empty`]); every lookup on it answers
    /// node 0 at master 0 (nothing panics), and no law runs one (the board builds its law
    /// only from a table that passed [`Self::rebuild_from_nodes`]).
    pub const fn empty() -> Self {
        Self {
            segs: Vec::new(),
            last: Node {
                master: Master::ZERO,
                slave_um: [PosUm::ZERO; S],
            },
        }
    }

    /// Validates the nodes and builds the table (SPEC §A "Table"), by value.
    ///
    /// A `CamTable` of 256 rows is 12 KiB: on a microcontroller build it in place in a
    /// static buffer with [`Self::rebuild_from_nodes`] instead (this returns it through
    /// the caller's stack frame).
    pub fn try_from_nodes(nodes: &[Node<S>], limits: &TableLimits<S>) -> Result<Self, TableError> {
        let mut t = Self::empty();
        t.rebuild_from_nodes(nodes, limits)?;
        Ok(t)
    }

    /// Validates the nodes and, only if every rule holds, rebuilds this table from them
    /// in place (SPEC §A "Table"; the rules are in the module docs). On an error the
    /// table is unchanged: a refused upload never harms the table in the buffer.
    ///
    /// Two passes over the nodes — the first checks every rule and writes nothing, the
    /// second writes the segments — so no segment array is ever built on the stack.
    pub fn rebuild_from_nodes(
        &mut self,
        nodes: &[Node<S>],
        limits: &TableLimits<S>,
    ) -> Result<(), TableError> {
        // Pass 1: every rule, nothing written.
        let last = build_segments(nodes, limits, N, MAX_LEN_BITS, |_| Ok(()))?;
        // Pass 2: the same walk, writing (the rules held, so it cannot fail here; the
        // capacity was checked in pass 1).
        self.segs.clear();
        let segs = &mut self.segs;
        let r = build_segments(nodes, limits, N, MAX_LEN_BITS, |seg| {
            segs.push(seg)
                .map_err(|_| TableError::TooManyNodes { capacity: N })
        });
        match r {
            Ok(_) => {
                self.last = last;
                Ok(())
            }
            Err(e) => {
                // Unreachable after pass 1; leave an empty (never runnable) table rather
                // than half of one.
                self.segs.clear();
                Err(e)
            }
        }
    }

    /// Makes this the [`Self::empty`] placeholder again, in place.
    pub fn clear(&mut self) {
        self.segs.clear();
        self.last = Node {
            master: Master::ZERO,
            slave_um: [PosUm::ZERO; S],
        };
    }

    /// Makes this table a copy of `other`, in place (no temporary on the stack).
    pub fn copy_from(&mut self, other: &Self) {
        self.segs.clear();
        // Same capacity N: cannot fail.
        let _ = self.segs.extend_from_slice(&other.segs);
        self.last = other.last;
    }

    /// Checks this (already built) table against other limits — e.g. after a limit
    /// parameter changed — with the rules of [`Self::try_from_nodes`] that depend on the
    /// limits: positions within range, slopes within the axis top speed at the master top
    /// speed. Rows count in increasing master order.
    pub fn check_limits(&self, limits: &TableLimits<S>) -> Result<(), TableError> {
        if limits.master_speed_per_s <= MasterRate::ZERO {
            return Err(TableError::MasterSpeed);
        }
        // Same order as building: node 0, then per segment its end node and its slope.
        for row in 0..self.len() {
            let node = self.node(row).ok_or(TableError::TooFewNodes)?;
            check_range(row, &node, limits)?;
            let Some(seg) = row.checked_sub(1).and_then(|k| self.segs.get(k)) else {
                continue;
            };
            for (axis, (d, lim)) in seg.dx.iter().zip(limits.axes.iter()).enumerate() {
                check_slope(row, axis, i64::from(*d), i64::from(seg.len), lim, limits)?;
            }
        }
        Ok(())
    }

    /// Number of nodes (0 for [`Self::empty`]; a built table has at least two).
    pub fn len(&self) -> usize {
        if self.segs.is_empty() {
            0
        } else {
            self.segs.len().saturating_add(1)
        }
    }

    /// Whether this is the [`Self::empty`] placeholder (a built table never is).
    pub fn is_empty(&self) -> bool {
        self.segs.is_empty()
    }

    /// Node `i` in increasing master order.
    pub fn node(&self, i: usize) -> Option<Node<S>> {
        if self.segs.is_empty() {
            return None;
        }
        if i == self.segs.len() {
            return Some(self.last);
        }
        self.segs.get(i).map(|s| {
            let mut slave_um = [PosUm::ZERO; S];
            for (o, x) in slave_um.iter_mut().zip(s.x0.iter()) {
                *o = PosUm::from_bits(*x);
            }
            Node {
                master: Master::from_bits(s.m0),
                slave_um,
            }
        })
    }

    /// The first (lowest) master value.
    pub fn master_first(&self) -> Master {
        Master::from_bits(
            self.segs
                .first()
                .map_or(self.last.master.to_bits(), |s| s.m0),
        )
    }

    /// The last (highest) master value.
    pub fn master_last(&self) -> Master {
        self.last.master
    }

    /// Locates `m`, starting the search at `*cursor` and leaving the found segment there.
    ///
    /// Fast path: the master is still in the cursor's segment, 0 ≤ θ − θ_j < len_j (one
    /// 64-bit subtraction and compare); otherwise the walk below.
    #[inline]
    pub fn locate(&self, cursor: &mut usize, m: Master) -> Lookup {
        let m = m.to_bits();
        if let Some(s) = self.segs.get(*cursor) {
            if let Some(d) = s.offset(m) {
                return Lookup {
                    seg: *cursor,
                    frac_q32: frac_q32(d, s.recip),
                    beyond: Beyond::Inside,
                };
            }
        }
        self.locate_walk(cursor, m)
    }

    /// [`CamTable::locate`] for a caller that needs only the segment (and which end the
    /// master is beyond), not the fraction: the feed-forward's rates. Its fast path skips
    /// the fraction's product; `frac_q32` is then 0 (off the fast path it is the true
    /// fraction).
    #[inline]
    pub(crate) fn locate_segment(&self, cursor: &mut usize, m: Master) -> Lookup {
        let m = m.to_bits();
        if let Some(s) = self.segs.get(*cursor) {
            if s.offset(m).is_some() {
                return Lookup {
                    seg: *cursor,
                    frac_q32: 0,
                    beyond: Beyond::Inside,
                };
            }
        }
        self.locate_walk(cursor, m)
    }

    /// The segment search of [`CamTable::locate`] when the master has left the cursor's
    /// segment (every ~160 ticks on the reference machine).
    #[inline(never)]
    fn locate_walk(&self, cursor: &mut usize, m: i64) -> Lookup {
        let last_seg = self.segs.len().saturating_sub(1);
        let mut j = (*cursor).min(last_seg);
        // Walk down while θ < θ_j, up while θ ≥ θ_{j+1}.
        while j > 0 && self.segs.get(j).is_some_and(|s| m < s.m0) {
            j = j.saturating_sub(1);
        }
        while j < last_seg
            && self
                .segs
                .get(j.saturating_add(1))
                .is_some_and(|s| m >= s.m0)
        {
            j = j.saturating_add(1);
        }
        *cursor = j;
        let Some(s) = self.segs.get(j) else {
            return Lookup::default();
        };
        if m < s.m0 {
            return Lookup {
                seg: j,
                frac_q32: 0,
                beyond: Beyond::Low,
            };
        }
        if m >= self.last.master.to_bits() {
            return Lookup {
                seg: j,
                frac_q32: u32::MAX,
                beyond: Beyond::High,
            };
        }
        // 0 ≤ d ≤ len − 1 < 2^32.
        let d = m.wrapping_sub(s.m0) as u64 & 0xFFFF_FFFF;
        Lookup {
            seg: j,
            frac_q32: frac_q32(d as u32, s.recip),
            beyond: Beyond::Inside,
        }
    }

    /// Slave `axis` at a located master value, µm (the end value beyond an end).
    #[inline]
    pub fn value(&self, lk: &Lookup, axis: usize) -> PosUm {
        let bits = match lk.beyond {
            Beyond::High => self.last.slave_um.get(axis).map_or(0, |x| x.to_bits()),
            _ => self.segs.get(lk.seg).map_or(0, |s| {
                let x0 = s.x0.get(axis).copied().unwrap_or(0);
                let dx = s.dx.get(axis).copied().unwrap_or(0);
                if lk.beyond == Beyond::Low {
                    return x0;
                }
                // |dx|·2^32 < 2^63; rounded to nearest; between x_j and x_{j+1}.
                let p = i64::from(dx).wrapping_mul(i64::from(lk.frac_q32));
                let step = (p.wrapping_add(1 << 31) >> 32) as i32;
                x0.saturating_add(step)
            }),
        };
        PosUm::from_bits(bits)
    }

    /// The rise of slave `axis` over segment `seg`, µm (0 beyond the ends).
    #[inline]
    pub fn rise(&self, lk: &Lookup, axis: usize) -> PosUm {
        if lk.beyond != Beyond::Inside {
            return PosUm::ZERO;
        }
        PosUm::from_bits(
            self.segs
                .get(lk.seg)
                .and_then(|s| s.dx.get(axis).copied())
                .unwrap_or(0),
        )
    }

    /// A master rate in segments per unit time, Q16.16: `rate / len_seg` for a rate in
    /// master counts per unit time, Q24.8 (0 beyond the ends). Multiplied by a slave's
    /// rise it gives that slave's target speed (or acceleration, for a master
    /// acceleration). One 32×32→64-bit product and a shift; relative error < 2^-30.
    #[inline]
    pub fn seg_rate_q16(&self, lk: &Lookup, rate_q8: i32) -> i32 {
        if lk.beyond != Beyond::Inside {
            return 0;
        }
        let Some(s) = self.segs.get(lk.seg) else {
            return 0;
        };
        s.rate_q16(rate_q8)
    }

    /// The follower's fast path for its lookups: the sampled master `sampled`, the
    /// filtered master now, `m`, and the look-ahead `m + delta()` (raw `I48F16`) all
    /// inside the cursor's segment — nearly every tick, since the filter's error and the
    /// look-ahead are a few periods of motion and a segment many. Gives the span at `m`
    /// (which is also the look-ahead's segment); `None` sends the caller to
    /// [`CamTable::locate`] and [`CamTable::locate_segment`]. `delta` is called only
    /// once the first two are known to be inside.
    #[inline(always)]
    pub(crate) fn span_pair(
        &self,
        cursor: usize,
        sampled: Master,
        m: Master,
        delta: impl FnOnce() -> i64,
    ) -> Option<Span<'_, S>> {
        let s = self.segs.get(cursor)?;
        s.offset(sampled.to_bits())?;
        let d = s.offset(m.to_bits())?;
        // The look-ahead's offset, modulo 2^64 like `d` (|delta| < 2^45, see
        // `MasterFilter::ahead`).
        if i64::from(d).wrapping_add(delta()) as u64 >= u64::from(s.len) {
            return None;
        }
        Some(Span {
            seg: s,
            frac_q32: frac_q32(d, s.recip),
        })
    }
}

/// A located segment as the follower's axis loop reads it: the segment's start values
/// x_j and rises Δx_j (raw `I24F8` µm, one per slave) and the fraction through it.
///
/// Beyond an end the lookup already points at an end segment with the fraction clamped
/// (below the first node: segment 0, fraction 0; at or above the last: the last segment,
/// fraction 2^32 − 1), and [`Span::value_bits`] then gives that end's node value exactly:
/// x_j + round(Δx_j·(2^32 − 1)/2^32) = x_j + Δx_j for |Δx_j| < 2^31, because
/// Δx·(2^32 − 1) + 2^31 = Δx·2^32 + (2^31 − Δx) with 0 < 2^31 − Δx < 2^32. So the loop needs
/// no per-axis test of the ends (the follower's feed-forward lookup reports the end and
/// gives no feed-forward there).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Span<'a, const S: usize> {
    seg: &'a Segment<S>,
    frac_q32: u32,
}

impl<const S: usize> Span<'_, S> {
    /// x*(θ) = x_j + round(Δx_j·frac / 2^32), raw `I24F8` µm (0 for a column beyond `S`).
    #[inline(always)]
    pub(crate) fn value_bits(&self, axis: usize) -> i32 {
        let x0 = self.seg.x0.get(axis).copied().unwrap_or(0);
        let dx = self.seg.dx.get(axis).copied().unwrap_or(0);
        // |dx|·2^32 < 2^63; rounded to nearest; between x_j and x_{j+1}.
        let p = i64::from(dx).wrapping_mul(i64::from(self.frac_q32));
        x0.saturating_add((p.wrapping_add(1 << 31) >> 32) as i32)
    }

    /// x_j, raw `I24F8` µm.
    #[inline(always)]
    pub(crate) fn start_bits(&self, axis: usize) -> i32 {
        self.seg.x0.get(axis).copied().unwrap_or(0)
    }

    /// Δx_j, raw `I24F8` µm.
    #[inline(always)]
    pub(crate) fn rise_bits(&self, axis: usize) -> i32 {
        self.seg.dx.get(axis).copied().unwrap_or(0)
    }

    /// The segment's floating reciprocal 2^24/len_j ≈ m·2^-s (raw `I48F16` len_j), as
    /// (m, s): m ∈ [2^31, 2^32), s ∈ 8 … 40.
    #[inline(always)]
    pub(crate) fn recip(&self) -> (u32, u32) {
        (self.seg.recip_m, self.seg.recip_s)
    }
}

impl<const S: usize, const N: usize> CamTable<S, N> {
    /// The segment of a lookup from [`CamTable::locate`] (`None` only for a lookup that
    /// did not come from this table).
    #[inline(always)]
    pub(crate) fn span(&self, lk: &Lookup) -> Option<Span<'_, S>> {
        self.segs.get(lk.seg).map(|s| Span {
            seg: s,
            frac_q32: lk.frac_q32,
        })
    }
}

/// The walk of [`CamTable::rebuild_from_nodes`]: checks every rule over `nodes` (at most
/// `capacity` of them) and hands each segment, in increasing master order, to `put`.
/// Returns the last node (in increasing master order).
fn build_segments<const S: usize>(
    nodes: &[Node<S>],
    limits: &TableLimits<S>,
    capacity: usize,
    max_len_bits: i64,
    mut put: impl FnMut(Segment<S>) -> Result<(), TableError>,
) -> Result<Node<S>, TableError> {
    if nodes.len() < 2 {
        return Err(TableError::TooFewNodes);
    }
    if nodes.len() > capacity {
        return Err(TableError::TooManyNodes { capacity });
    }
    if limits.master_speed_per_s <= MasterRate::ZERO {
        return Err(TableError::MasterSpeed);
    }
    let (first, rest) = nodes.split_first().ok_or(TableError::TooFewNodes)?;
    let decreasing = rest.first().is_some_and(|n| n.master < first.master);
    // Rows in increasing master order, with their original indices.
    let at = |i: usize| -> Option<(usize, &Node<S>)> {
        let len = nodes.len();
        let idx = if decreasing {
            len.checked_sub(1)?.checked_sub(i)?
        } else {
            i
        };
        nodes.get(idx).map(|n| (idx, n))
    };
    let mut prev: Option<(usize, &Node<S>)> = None;
    for i in 0..nodes.len() {
        let (row, node) = at(i).ok_or(TableError::TooFewNodes)?;
        check_range(row, node, limits)?;
        if let Some((_, p)) = prev {
            let len = node.master.to_bits().checked_sub(p.master.to_bits());
            let len = match len {
                Some(l) if l > 0 => l,
                _ => return Err(TableError::NotMonotonic { row }),
            };
            if !(2..=max_len_bits).contains(&len) {
                return Err(TableError::SegmentLength { row });
            }
            let mut dx = [0i32; S];
            for (axis, ((d, (a, b)), lim)) in dx
                .iter_mut()
                .zip(p.slave_um.iter().zip(node.slave_um.iter()))
                .zip(limits.axes.iter())
                .enumerate()
            {
                let diff = i64::from(b.to_bits()).saturating_sub(i64::from(a.to_bits()));
                check_slope(row, axis, diff, len, lim, limits)?;
                *d = i32::try_from(diff).map_err(|_| TableError::TooSteep { row, axis })?;
            }
            let len_u = len.unsigned_abs();
            // ⌈2^64/len⌉ (len ≥ 2, so ≤ 2^63).
            let recip = u64::MAX.checked_div(len_u).unwrap_or(0).saturating_add(1);
            let mut x0 = [0i32; S];
            for (o, x) in x0.iter_mut().zip(p.slave_um.iter()) {
                *o = x.to_bits();
            }
            let (recip_m, recip_s) = float_recip(len_u);
            put(Segment {
                m0: p.master.to_bits(),
                len: u32::try_from(len_u).map_err(|_| TableError::SegmentLength { row })?,
                recip,
                recip_m,
                recip_s,
                x0,
                dx,
            })?;
        }
        prev = Some((row, node));
    }
    prev.map(|(_, n)| *n).ok_or(TableError::TooFewNodes)
}

/// Every slave position of `node` (row `row`) within its axis range.
fn check_range<const S: usize>(
    row: usize,
    node: &Node<S>,
    limits: &TableLimits<S>,
) -> Result<(), TableError> {
    for (axis, (x, lim)) in node.slave_um.iter().zip(limits.axes.iter()).enumerate() {
        if *x < lim.min_um || *x > lim.max_um {
            return Err(TableError::OutOfRange { row, axis });
        }
    }
    Ok(())
}

/// One segment's slope within the axis top speed at the master top speed:
/// |Δx|·θ̇_max ≤ v_max·len, both sides Q8·Q16 in `i128` (`diff_bits` Δx raw µm Q8,
/// `len_bits` raw master Q16; the segment ends at row `row`).
fn check_slope<const S: usize>(
    row: usize,
    axis: usize,
    diff_bits: i64,
    len_bits: i64,
    lim: &AxisLimits,
    limits: &TableLimits<S>,
) -> Result<(), TableError> {
    let lhs = i128::from(diff_bits.unsigned_abs())
        .saturating_mul(i128::from(limits.master_speed_per_s.to_bits()));
    let rhs = i128::from(lim.max_speed_um_per_s.to_bits()).saturating_mul(i128::from(len_bits));
    if lhs > rhs {
        Err(TableError::TooSteep { row, axis })
    } else {
        Ok(())
    }
}

/// The fraction d/len, Q0.32, for 0 ≤ d ≤ len − 1 and recip = ⌈2^64/len⌉.
///
/// recip < 2^64/len + 1, so d·recip < 2^64 − 2^64/len + len < 2^64 (2^64/len > 2^32 >
/// len), and (d·recip) >> 32 = d·r_hi + (d·r_lo >> 32) < 2^32 (two u32×u32 products).
/// Both terms and their sum are below 2^32, so the sum is one `umull` and one `mla` in
/// 32-bit words (no wrap).
#[inline(always)]
fn frac_q32(d: u32, recip: u64) -> u32 {
    let lo = (u64::from(d).wrapping_mul(recip & 0xFFFF_FFFF) >> 32) as u32;
    let hi = d.wrapping_mul((recip >> 32) as u32);
    hi.wrapping_add(lo)
}

/// (m, s) with m = ⌈2^(24+s) / len⌉ ∈ [2^31, 2^32), for 2 ≤ len < 2^32 (table build only).
pub(crate) fn float_recip(len: u64) -> (u32, u32) {
    let len = u128::from(len.max(2));
    let mut s = 0u32;
    while s < 64 {
        let num = 1u128
            .checked_shl(24u32.saturating_add(s))
            .unwrap_or(u128::MAX);
        let m = num.div_ceil(len);
        if m >= 1 << 31 {
            return (u32::try_from(m).unwrap_or(u32::MAX), s);
        }
        s = s.saturating_add(1);
    }
    (u32::MAX, 63)
}

#[cfg(test)]
mod in_place_tests;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn lim<const S: usize>() -> TableLimits<S> {
        TableLimits {
            master_speed_per_s: MasterRate::from_num(3000),
            axes: [AxisLimits {
                min_um: PosUm::from_num(-1_000_000),
                max_um: PosUm::from_num(1_000_000),
                max_speed_um_per_s: VelUmPerS::from_num(1_000_000),
            }; S],
        }
    }

    fn n1(m: f64, x: f64) -> Node<1> {
        Node {
            master: Master::from_num(m),
            slave_um: [PosUm::from_num(x)],
        }
    }

    #[test]
    fn interpolates_and_clamps() {
        let t: CamTable<1, 8> =
            CamTable::try_from_nodes(&[n1(0.0, 0.0), n1(100.0, 1000.0), n1(300.0, 0.0)], &lim())
                .unwrap();
        let mut c = 0;
        let v = |c: &mut usize, m: f64| {
            let lk = t.locate(c, Master::from_num(m));
            (t.value(&lk, 0).to_num::<f64>(), lk.beyond)
        };
        assert_eq!(v(&mut c, 50.0), (500.0, Beyond::Inside));
        assert!((v(&mut c, 200.0).0 - 500.0).abs() < 0.01);
        assert_eq!(v(&mut c, 300.0), (0.0, Beyond::High));
        assert_eq!(v(&mut c, 1e6), (0.0, Beyond::High));
        assert_eq!(v(&mut c, -5.0), (0.0, Beyond::Low));
        assert_eq!(v(&mut c, 100.0), (1000.0, Beyond::Inside));
        assert_eq!(t.master_first(), Master::ZERO);
        assert_eq!(t.master_last(), Master::from_num(300));
        assert_eq!(t.node(2), Some(n1(300.0, 0.0)));
    }

    #[test]
    fn decreasing_master_is_reversed() {
        let t: CamTable<1, 8> =
            CamTable::try_from_nodes(&[n1(10.0, 5.0), n1(0.0, 1.0)], &lim()).unwrap();
        assert_eq!(t.node(0), Some(n1(0.0, 1.0)));
        let mut c = 0;
        let lk = t.locate(&mut c, Master::from_num(5));
        assert_eq!(t.value(&lk, 0), PosUm::from_num(3));
    }

    #[test]
    fn typed_errors_name_the_row() {
        type T = CamTable<1, 4>;
        assert_eq!(
            T::try_from_nodes(&[n1(0.0, 0.0)], &lim()),
            Err(TableError::TooFewNodes)
        );
        let five = [
            n1(0.0, 0.0),
            n1(1.0, 0.0),
            n1(2.0, 0.0),
            n1(3.0, 0.0),
            n1(4.0, 0.0),
        ];
        assert_eq!(
            T::try_from_nodes(&five, &lim()),
            Err(TableError::TooManyNodes { capacity: 4 })
        );
        let bad = [n1(0.0, 0.0), n1(1.0, 0.0), n1(1.0, 0.0)];
        assert_eq!(
            T::try_from_nodes(&bad, &lim()),
            Err(TableError::NotMonotonic { row: 2 })
        );
        let bad = [n1(0.0, 0.0), n1(1.0, 0.0), n1(0.5, 0.0)];
        assert_eq!(
            T::try_from_nodes(&bad, &lim()),
            Err(TableError::NotMonotonic { row: 2 })
        );
        let bad = [n1(0.0, 0.0), n1(70_000.0, 0.0)];
        assert_eq!(
            T::try_from_nodes(&bad, &lim()),
            Err(TableError::SegmentLength { row: 1 })
        );
        let bad = [n1(0.0, 0.0), n1(1.0, 2e6)];
        assert_eq!(
            T::try_from_nodes(&bad, &lim()),
            Err(TableError::OutOfRange { row: 1, axis: 0 })
        );
        // 1000 µm per count at 3000 counts/s = 3 m/s > 1 m/s
        let bad = [n1(0.0, 0.0), n1(1.0, 10.0), n1(2.0, 1010.0)];
        assert_eq!(
            T::try_from_nodes(&bad, &lim()),
            Err(TableError::TooSteep { row: 2, axis: 0 })
        );
        let mut l = lim::<1>();
        l.master_speed_per_s = MasterRate::ZERO;
        assert_eq!(
            T::try_from_nodes(&[n1(0.0, 0.0), n1(1.0, 0.0)], &l),
            Err(TableError::MasterSpeed)
        );
    }

    #[test]
    fn segment_rate_gives_speed() {
        let t: CamTable<1, 4> =
            CamTable::try_from_nodes(&[n1(0.0, 0.0), n1(500.0, 6000.0)], &lim()).unwrap();
        let mut c = 0;
        let lk = t.locate(&mut c, Master::from_num(100));
        // 3000 counts/s over 500-count segments = 6 segments/s
        let r = t.seg_rate_q16(&lk, 3000 << 8);
        assert!((f64::from(r) / 65536.0 - 6.0).abs() < 1e-4);
        assert_eq!(t.rise(&lk, 0), PosUm::from_num(6000));
    }

    fn table_strategy() -> impl Strategy<Value = std::vec::Vec<(f64, f64, f64)>> {
        proptest::collection::vec(
            (1.0f64..2000.0, -400_000.0f64..400_000.0, -4000.0f64..4000.0),
            2..60,
        )
    }

    /// The nodes of a `table_strategy` draw (masters from `m0`, steps rounded to whole
    /// counts, at least 1) and the table built from them with the wide test limits.
    fn strategy_table(
        steps: &[(f64, f64, f64)],
        m0: f64,
    ) -> (std::vec::Vec<Node<2>>, CamTable<2, 64>) {
        let mut nodes = std::vec::Vec::new();
        let mut m = m0;
        for (dm, x, y) in steps {
            m += dm.round().max(1.0);
            nodes.push(Node {
                master: Master::from_num(m),
                slave_um: [PosUm::from_num(*x), PosUm::from_num(*y)],
            });
        }
        let mut l = lim::<2>();
        l.master_speed_per_s = MasterRate::from_num(1);
        let t = CamTable::try_from_nodes(&nodes, &l).unwrap();
        (nodes, t)
    }

    proptest! {
        /// The interpolated value lies between the bracketing nodes and equals an f64
        /// reference within 2 LSB (7.8 nm), for any cursor start.
        #[test]
        fn matches_f64_reference(steps in table_strategy(), probes in proptest::collection::vec(0.0f64..1.0, 1..40),
                                 start in 0usize..64) {
            let (nodes, t) = strategy_table(&steps, -10_000.0);
            let lo = nodes[0].master.to_num::<f64>();
            let hi = nodes[nodes.len() - 1].master.to_num::<f64>();
            let mut c = start;
            for p in probes {
                let mq = Master::from_num(lo + p * (hi - lo));
                let mf = mq.to_num::<f64>();
                let lk = t.locate(&mut c, mq);
                let j = nodes.iter().rposition(|n| n.master <= mq).unwrap();
                prop_assert_eq!(lk.seg, j.min(nodes.len() - 2));
                for axis in 0..2 {
                    let got = t.value(&lk, axis).to_num::<f64>();
                    let (a, b) = (&nodes[lk.seg], &nodes[lk.seg + 1]);
                    let (m0, m1) = (a.master.to_num::<f64>(), b.master.to_num::<f64>());
                    let (x0, x1) = (a.slave_um[axis].to_num::<f64>(), b.slave_um[axis].to_num::<f64>());
                    let want = x0 + (x1 - x0) * (mf - m0) / (m1 - m0);
                    prop_assert!((got - want).abs() <= 2.0 / 256.0, "got {} want {}", got, want);
                    prop_assert!(got >= x0.min(x1) && got <= x0.max(x1));
                }
            }
        }

        /// The segment rate equals rate/len within 1e-9 relative + 1 LSB, for segment
        /// lengths on both sides of the 256-count split of its two shift paths.
        #[test]
        fn segment_rate_matches_f64(len_raw in 2i64..(1i64 << 32) - (1 << 16), rate in -(1i32 << 30)..(1i32 << 30)) {
            let t: CamTable<1, 4> = CamTable::try_from_nodes(
                &[Node { master: Master::ZERO, slave_um: [PosUm::ZERO] },
                  Node { master: Master::from_bits(len_raw), slave_um: [PosUm::ZERO] }], &lim()).unwrap();
            let mut c = 0;
            let lk = t.locate(&mut c, Master::ZERO);
            let got = f64::from(t.seg_rate_q16(&lk, rate));
            let want = (f64::from(rate) / 256.0 / (len_raw as f64 / 65536.0) * 65536.0)
                .clamp(f64::from(i32::MIN), f64::from(i32::MAX));
            prop_assert!((got - want).abs() <= want.abs() * 1e-9 + 1.0, "got {} want {}", got, want);
        }

        /// The follower's span reads the same values as [`CamTable::value`], beyond the
        /// ends too.
        #[test]
        fn span_matches_value(steps in table_strategy(), probes in proptest::collection::vec(-0.2f64..1.2, 1..40)) {
            let (nodes, t) = strategy_table(&steps, -10_000.0);
            let lo = nodes[0].master.to_num::<f64>();
            let hi = nodes[nodes.len() - 1].master.to_num::<f64>();
            let mut c = 0;
            for p in probes {
                let lk = t.locate(&mut c, Master::from_num(lo + p * (hi - lo)));
                let sp = t.span(&lk).unwrap();
                for axis in 0..2 {
                    prop_assert_eq!(sp.value_bits(axis), t.value(&lk, axis).to_bits());
                }
            }
        }

        /// `locate_segment` finds the segment (and the end beyond) that `locate` finds,
        /// from the same cursor.
        /// The follower's fast path: `Some` exactly when the sampled master, the master
        /// and its look-ahead are all in the cursor's segment, then with the span
        /// `locate` gives at the master; the look-ahead is computed only then.
        #[test]
        fn span_pair_is_the_in_segment_case(steps in table_strategy(),
                                            probes in proptest::collection::vec((-0.2f64..1.2, -0.05f64..0.05, -0.05f64..0.05), 1..40)) {
            let (nodes, t) = strategy_table(&steps, -10_000.0);
            let lo = nodes[0].master.to_num::<f64>();
            let hi = nodes[nodes.len() - 1].master.to_num::<f64>();
            let mut c = 0;
            for (p, ds, da) in probes {
                let m = Master::from_num(lo + p * (hi - lo));
                let sampled = Master::from_num(lo + (p + ds) * (hi - lo));
                let delta = Master::from_num(da * (hi - lo)).to_bits();
                let cursor = c;
                let mut asked = false;
                let got = t.span_pair(cursor, sampled, m, || {
                    asked = true;
                    delta
                });
                let seg = t.segs[cursor];
                let inside = |x: i64| x >= seg.m0 && x < seg.m0 + i64::from(seg.len);
                let all = inside(sampled.to_bits()) && inside(m.to_bits()) && inside(m.to_bits() + delta);
                prop_assert_eq!(got.is_some(), all);
                prop_assert_eq!(asked, inside(sampled.to_bits()) && inside(m.to_bits()));
                if let Some(sp) = got {
                    let lk = t.locate(&mut c, m);
                    prop_assert_eq!(lk.seg, cursor);
                    for axis in 0..2 {
                        prop_assert_eq!(sp.value_bits(axis), t.value(&lk, axis).to_bits());
                    }
                } else {
                    let _ = t.locate(&mut c, m);
                }
            }
        }

        #[test]
        fn locate_segment_agrees_with_locate(steps in table_strategy(), probes in proptest::collection::vec(-0.2f64..1.2, 1..40)) {
            let (nodes, t) = strategy_table(&steps, -10_000.0);
            let lo = nodes[0].master.to_num::<f64>();
            let hi = nodes[nodes.len() - 1].master.to_num::<f64>();
            let (mut c1, mut c2) = (0, 0);
            for p in probes {
                let m = Master::from_num(lo + p * (hi - lo));
                let a = t.locate(&mut c1, m);
                let b = t.locate_segment(&mut c2, m);
                prop_assert_eq!((a.seg, a.beyond), (b.seg, b.beyond));
                prop_assert_eq!(c1, c2);
            }
        }

        #[test]
        /// A built table checked against other limits gives the verdict (and the error)
        /// that building it with those limits gives.
        #[test]
        fn check_limits_agrees_with_building(steps in table_strategy(), max_um in 0.0f64..400_000.0,
                                             v_max in 1_000.0f64..1_000_000.0, master_speed in 1.0f64..3000.0) {
            let (nodes, t) = strategy_table(&steps, 0.0);
            let mut wide = lim::<2>();
            wide.master_speed_per_s = MasterRate::from_num(1);
            prop_assert_eq!(t.check_limits(&wide), Ok(()));
            let mut other = lim::<2>();
            other.master_speed_per_s = MasterRate::from_num(master_speed);
            other.axes[1].min_um = PosUm::from_num(-max_um);
            other.axes[1].max_um = PosUm::from_num(max_um);
            other.axes[0].max_speed_um_per_s = VelUmPerS::from_num(v_max);
            let built = CamTable::<2, 64>::try_from_nodes(&nodes, &other).map(|_| ());
            prop_assert_eq!(t.check_limits(&other), built);
        }

        fn never_panics(ms in proptest::collection::vec(any::<i64>(), 0..10), xs in any::<i32>(), q in any::<i64>(),
                        c0 in any::<usize>(), rate in any::<i32>()) {
            let nodes: std::vec::Vec<Node<1>> = ms.iter().map(|m| Node { master: Master::from_bits(*m), slave_um: [PosUm::from_bits(xs)] }).collect();
            if let Ok(t) = CamTable::<1, 16>::try_from_nodes(&nodes, &lim()) {
                let mut c = c0;
                let lk = t.locate(&mut c, Master::from_bits(q));
                let _ = t.value(&lk, 0);
                let _ = t.value(&lk, 5);
                let _ = t.seg_rate_q16(&lk, rate);
            }
        }
    }
}
