//! Design columns without storing them: the ten rigid-body columns are computed block by
//! block from the signals ([`Blocks`]) wherever the fit reads them (Gram products, the
//! blocked QR, predictions, residuals), instead of being kept as `39 n` values for a log of
//! `n` samples (0.3 GB at a million samples).

use tagk_dynamics::write_rigid_body_regressor;

use crate::fit::design::ColData;
use crate::signals::Signals;

/// Samples per block of [`Blocks`]: the rigid-body columns of one block (`60 ×` this many
/// values, 0.5 MB) stay in cache while every cross product of the block reads them. A
/// multiple of 4, so that the four interleaved partial sums of the Gram products carry over
/// from block to block exactly as over one long column.
pub(crate) const BLOCK_SAMPLES: usize = 1024;

/// Distance between two rows of [`Blocks`]' rigid-body buffer: a block plus one cache line,
/// so that the 60 rows written for one sample do not all fall on the same cache sets (rows
/// a power of two apart would).
const ROW_STRIDE: usize = BLOCK_SAMPLES + 8;

/// The regressor entries `10 c + j` (channel `c`, column `j`) that the design uses
/// ([`rigid_channels`]); the other 21 are zero by construction.
const RIGID_ENTRIES: [usize; 39] = [
    0, 10, 20, // mass: the forces
    1, 11, 21, 31, 41, 51, // first moments: every channel
    2, 12, 22, 32, 42, 52, //
    3, 13, 23, 33, 43, 53, //
    34, 44, 54, 35, 45, 55, // inertia: the torques
    36, 46, 56, 37, 47, 57, //
    38, 48, 58, 39, 49, 59, //
];

/// The channels on which rigid-body column `j` (order of `tagk_dynamics::InertialParams`)
/// has values: the mass on the forces, the first moments on every channel, the inertia on
/// the torques.
pub(crate) fn rigid_channels(j: usize) -> &'static [usize] {
    match j {
        0 => &[0, 1, 2],
        1..=3 => &[0, 1, 2, 3, 4, 5],
        _ => &[3, 4, 5],
    }
}

/// A column of the regression design.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Column<'a> {
    /// Values kept in memory (an effect's column, a weighted target).
    Stored(&'a ColData),
    /// Values kept at the samples `0, stride, 2 stride, …` only, `stride` being that of the
    /// blocks that read them ([`Blocks::load`] from a multiple of it): a scanned candidate's
    /// columns in a scan ([`crate::fit::design::sampled_effect_design`]).
    Sampled(&'a ColData),
    /// Values kept at the samples `start..start + len` only (`len` the vectors' length), read
    /// at stride 1: a scanned filtering candidate's columns on a scan window
    /// ([`crate::fit::design::window_effect_design`]).
    Window(&'a ColData, usize),
    /// Rigid-body column `j` (`0..10`), computed per block from the signals.
    Rigid(usize),
    /// The regression target (per-sample rows of the six channels, given to
    /// [`Blocks::new`]), read per block.
    Target,
}

impl<'a> Column<'a> {
    /// Stored columns, borrowed.
    pub fn stored(cols: &'a [ColData]) -> impl Iterator<Item = Column<'a>> + 'a {
        cols.iter().map(Column::Stored)
    }

    /// `true` if the column has values on channel `c`.
    pub fn has(&self, c: usize) -> bool {
        match self {
            Column::Stored(d) | Column::Sampled(d) | Column::Window(d, _) => d[c].is_some(),
            Column::Rigid(j) => rigid_channels(*j).contains(&c),
            Column::Target => true,
        }
    }

    /// `true` for a rigid-body column.
    pub fn is_rigid(&self) -> bool {
        matches!(self, Column::Rigid(_))
    }

    /// `true` if both are the same column (the same stored values, or the same rigid-body
    /// column).
    pub fn same(&self, other: &Column<'_>) -> bool {
        match (self, other) {
            (Column::Stored(a), Column::Stored(b)) | (Column::Sampled(a), Column::Sampled(b)) => {
                std::ptr::eq(*a, *b)
            }
            (Column::Window(a, i), Column::Window(b, j)) => std::ptr::eq(*a, *b) && i == j,
            (Column::Rigid(a), Column::Rigid(b)) => a == b,
            (Column::Target, Column::Target) => true,
            _ => false,
        }
    }
}

std::thread_local! {
    /// The block buffers of the last [`Blocks`] dropped on this thread, for the next one:
    /// the Gram engine makes a block reader per product (thousands in a diagnosis), and a
    /// fresh half-megabyte buffer each time costs page faults and zeroing.
    static SPARE_BUFFERS: std::cell::RefCell<(Vec<f64>, Vec<f64>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// One block of samples of the design: samples `lo, lo + stride, …` below `hi` (at most
/// [`BLOCK_SAMPLES`] of them), with the rigid-body columns computed for them and the target's
/// channels gathered, when the columns read need them ([`Blocks::need`]).
pub(crate) struct Blocks<'s> {
    s: &'s Signals,
    /// The target's rows ([`Column::Target`]).
    target: Option<&'s [[f64; 6]]>,
    /// The target's channels at the block's samples, `[c][m]`.
    target_block: Vec<f64>,
    need_rigid: bool,
    need_target: bool,
    /// Rigid-body regressor entries of the block, `[10 c + j][m]` (row-major `Y`, one row
    /// of [`ROW_STRIDE`] per entry).
    rigid: Vec<f64>,
    lo: usize,
    hi: usize,
    stride: usize,
}

impl<'s> Blocks<'s> {
    /// A block reader over the signals `s` and the target rows `target` (nothing loaded
    /// yet, nothing needed).
    pub fn new(s: &'s Signals, target: Option<&'s [[f64; 6]]>) -> Self {
        let (rigid, target_block) = SPARE_BUFFERS.with(|b| std::mem::take(&mut *b.borrow_mut()));
        Self {
            s,
            target,
            target_block,
            need_rigid: false,
            need_target: false,
            rigid,
            lo: 0,
            hi: 0,
            stride: 1,
        }
    }

    /// Makes the blocks loaded from now on serve `cols` (the rigid-body columns computed,
    /// the target gathered, if any of them is one).
    pub fn need(&mut self, cols: &[Column<'_>]) {
        self.need_rigid |= cols.iter().any(Column::is_rigid);
        self.need_target |= cols.iter().any(|c| matches!(c, Column::Target));
    }

    /// Loads the samples `lo, lo + stride, …` below `hi` (at most [`BLOCK_SAMPLES`]).
    pub fn load(&mut self, lo: usize, hi: usize, stride: usize) {
        debug_assert!(stride >= 1 && (hi - lo).div_ceil(stride) <= BLOCK_SAMPLES);
        self.lo = lo;
        self.hi = hi;
        self.stride = stride;
        if self.need_target
            && let Some(target) = self.target
        {
            if self.target_block.is_empty() {
                self.target_block = vec![0.0; 6 * BLOCK_SAMPLES];
            }
            for (m, i) in (lo..hi).step_by(stride).enumerate() {
                for c in 0..6 {
                    self.target_block[c * BLOCK_SAMPLES + m] = target[i][c];
                }
            }
        }
        if !self.need_rigid {
            return;
        }
        // A cached regressor is read in place at stride 1 ([`Blocks::get`]).
        if stride == 1 && self.s.rigid_cache().is_some() {
            return;
        }
        if self.rigid.is_empty() {
            self.rigid = vec![0.0; 60 * ROW_STRIDE];
        }
        let s = self.s;
        // Eight samples' regressors at a time, then each entry's eight values written
        // together: one row segment per entry instead of 39 scattered writes per sample.
        const TILE: usize = 8;
        let samples: Vec<usize> = (lo..hi).step_by(stride).collect();
        let mut y = [[0.0; 60]; TILE];
        for (t, chunk) in samples.chunks(TILE).enumerate() {
            for (yk, &i) in y.iter_mut().zip(chunk) {
                // Infallible: the buffer has 60 entries.
                let _ = write_rigid_body_regressor(
                    &s.accel_proper[i],
                    &s.omega(i),
                    &s.omega_dot(i),
                    yk,
                );
            }
            let m0 = t * TILE;
            for q in RIGID_ENTRIES {
                let row = &mut self.rigid[q * ROW_STRIDE + m0..q * ROW_STRIDE + m0 + chunk.len()];
                for (r, yk) in row.iter_mut().zip(&y) {
                    *r = yk[q];
                }
            }
        }
    }

    /// The values of `col` on channel `c` at the loaded samples: a slice and the step
    /// between the loaded samples in it (`None` where the column has no values). A rigid-body
    /// column or the target must have been needed ([`Blocks::need`]) before the load.
    pub fn get<'b>(&'b self, col: &Column<'b>, c: usize) -> Option<(&'b [f64], usize)> {
        match col {
            Column::Stored(d) => d[c].as_ref().map(|v| (&v[self.lo..self.hi], self.stride)),
            Column::Window(d, start) => d[c].as_ref().map(|v| {
                assert_eq!(self.stride, 1, "window column read at a stride");
                (&v[self.lo - start..self.hi - start], 1)
            }),
            Column::Sampled(d) => d[c].as_ref().map(|v| {
                // The blocks of a scan start at multiples of the stride (one piece from 0).
                assert_eq!(
                    self.lo % self.stride,
                    0,
                    "sampled column read off its samples"
                );
                let first = self.lo / self.stride;
                let count = (self.hi - self.lo).div_ceil(self.stride);
                (&v[first..first + count], 1)
            }),
            Column::Rigid(j) => {
                if !rigid_channels(*j).contains(&c) {
                    return None;
                }
                if self.stride == 1
                    && let Some(cache) = self.s.rigid_cache()
                {
                    return Some((&cache[10 * c + j][self.lo..self.hi], 1));
                }
                let count = (self.hi - self.lo).div_ceil(self.stride);
                let row = (10 * c + j) * ROW_STRIDE;
                Some((&self.rigid[row..row + count], 1))
            }
            Column::Target => {
                let count = (self.hi - self.lo).div_ceil(self.stride);
                let row = c * BLOCK_SAMPLES;
                Some((&self.target_block[row..row + count], 1))
            }
        }
    }
}

impl Drop for Blocks<'_> {
    fn drop(&mut self) {
        let buffers = (
            std::mem::take(&mut self.rigid),
            std::mem::take(&mut self.target_block),
        );
        SPARE_BUFFERS.with(|b| *b.borrow_mut() = buffers);
    }
}

/// Calls `f(lo, hi)` for the blocks of `range` ([`BLOCK_SAMPLES`] samples each, stride 1),
/// after loading them into `blocks`.
pub(crate) fn for_each_block(
    blocks: &mut Blocks<'_>,
    range: std::ops::Range<usize>,
    mut f: impl FnMut(&Blocks<'_>, usize, usize),
) {
    let mut lo = range.start;
    while lo < range.end {
        let hi = (lo + BLOCK_SAMPLES).min(range.end);
        blocks.load(lo, hi, 1);
        f(blocks, lo, hi);
        lo = hi;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The entries a block computes are exactly those of the columns' channels.
    #[test]
    fn rigid_entries_are_the_columns_channels() {
        let mut want: Vec<usize> = (0..10)
            .flat_map(|j| rigid_channels(j).iter().map(move |c| 10 * c + j))
            .collect();
        let mut got = RIGID_ENTRIES.to_vec();
        want.sort_unstable();
        got.sort_unstable();
        assert_eq!(got, want);
    }
}
