//! The Gram-matrix engine behind the blocked cross-validation and the 1-D scans.

use std::borrow::Borrow;

use nalgebra::{DMatrix, DVector};

use crate::fit::columns::{BLOCK_SAMPLES, Blocks, Column, for_each_block};
use crate::fit::design::ColData;
use crate::signals::Signals;

/// Evaluation of a candidate set of extra columns by the [`GramEngine`].
#[derive(Debug, Clone)]
pub(crate) struct Evaluation {
    /// Weighted in-sample SSE with the candidate.
    pub sse_full: f64,
    /// Its part per channel.
    pub sse_full_ch: [f64; 6],
    /// Held-out SSE per channel.
    pub sse_cv_ch: [f64; 6],
    /// Full-data coefficients (base deltas then candidate).
    pub beta: Vec<f64>,
    /// Diagonal of the (pseudo-)inverse weighted Gram matrix: `σ² κ ·` this is the variance.
    pub cov_diag: Vec<f64>,
    /// Diagonal of the weighted Gram matrix of the columns (base then candidate): with
    /// [`Evaluation::cov_diag`] it gives each coefficient's variance inflation factor,
    /// `cov_diag_j · gram_diag_j` (1: orthogonal to the other columns).
    pub gram_diag: Vec<f64>,
    /// The same diagonal per channel: how much of each coefficient's information each channel
    /// carries (for a variance that weighs each channel's own residual scale).
    pub gram_diag_ch: Vec<[f64; 6]>,
    /// Per cross-validation fold, the coefficients fitted without it (empty without folds):
    /// what [`GramEngine::held_out_residual`] predicts each held-out block with.
    pub fold_beta: Vec<Vec<f64>>,
}

impl Evaluation {
    /// Held-out SSE, summed over the channels.
    pub fn sse_cv(&self) -> f64 {
        self.sse_cv_ch.iter().sum()
    }

    /// Variance inflation factor of coefficient `j` (base columns first): how much the other
    /// columns inflate its variance (`1 / (1 − R²)` of the column on the others, uncentred);
    /// infinite for a coefficient the data do not determine.
    pub fn inflation(&self, j: usize) -> f64 {
        let v = self.cov_diag[j] * self.gram_diag[j];
        if v.is_finite() {
            v.max(1.0)
        } else {
            f64::INFINITY
        }
    }
}

/// Gram-matrix engine: the weighted target `y` and the base columns are reduced once to
/// per-piece, per-channel cross-product matrices; each candidate only adds its own cross
/// products. Every operand (target, base, candidate, offset) is weighted on the fly by the
/// channel weights: `(x w)(y w)` per sample, the same bits as from stored weighted copies. Pieces implement blocked K-fold cross-validation over time with a buffer of
/// `buffer` samples on each side of the held-out block removed from training (so that
/// autocorrelated neighbours do not leak).
pub(crate) struct GramEngine<'a> {
    s: &'a Signals,
    w: [f64; 6],
    /// The unweighted target rows, borrowed (weighted on the fly by `w`, [`Column::Target`]:
    /// the same products as with a stored weighted copy, without the copy).
    target: &'a [[f64; 6]],
    /// The base columns, unweighted, borrowed or computed per block (weighted on the fly by
    /// `w` in the cross products and the residual: no weighted copy of a long log's design
    /// is kept, and no copy of the rigid-body columns at all).
    base: Vec<Column<'a>>,
    pieces: Vec<(usize, usize)>,
    folds: usize,
    /// Every `stride`-th sample enters the cross products (1: all; more in scan engines).
    /// Per piece, per channel: (1+p0)² cross products of [y, base…].
    base_gram: Vec<f64>,
    stride: usize,
    /// The supports of `[target, base…]` ([`Support`]), scanned once per engine.
    support: Vec<Support>,
}

/// Shortest block of the blocked cross-validation \[s\] ([`GramEngine::new`]).
const MIN_BLOCK_SECONDS: f64 = 3.0;

/// Most blocks per fold of the blocked cross-validation.
const MAX_BLOCK_ROUNDS: usize = 8;

/// Samples a 1-D scan looks at, at most (about): a scan ranks the values of one parameter by
/// their in-sample residual, for which every `n / SCAN_SAMPLES`-th sample of a long log
/// suffices; the chosen value is then evaluated on every sample.
pub(crate) const SCAN_SAMPLES: usize = 10_000;

impl<'a> GramEngine<'a> {
    /// `target`: the unweighted target (the measured wrench when `None`).
    pub fn new(
        s: &'a Signals,
        w: &[f64; 6],
        base: &[Column<'a>],
        target: Option<&'a [[f64; 6]]>,
        folds: usize,
    ) -> Self {
        Self::with_stride(s, w, base, target, folds, 1)
    }

    /// An engine for a scan from the start ([`GramEngine::for_scan`] without the full-size
    /// cross products first): no folds, every `n / SCAN_SAMPLES`-th sample.
    pub fn new_for_scan(
        s: &'a Signals,
        w: &[f64; 6],
        base: &[Column<'a>],
        target: Option<&'a [[f64; 6]]>,
    ) -> Self {
        Self::with_stride(s, w, base, target, 1, (s.len() / SCAN_SAMPLES).max(1))
    }

    /// An engine over the contiguous samples `range` only (every sample, no folds): the
    /// in-sample scan of a long log's filtered effect on a window of it.
    pub fn new_window(
        s: &'a Signals,
        w: &[f64; 6],
        base: &[Column<'a>],
        target: Option<&'a [[f64; 6]]>,
        range: std::ops::Range<usize>,
    ) -> Self {
        Self::with_pieces(
            s,
            w,
            base,
            target,
            1,
            1,
            Some(vec![(range.start, range.end)]),
        )
    }

    /// The samples the engine's in-sample sums and residual run over: its one piece, or the
    /// whole log.
    pub fn span(&self) -> std::ops::Range<usize> {
        match self.pieces.as_slice() {
            [(lo, hi)] => *lo..*hi,
            _ => 0..self.s.len(),
        }
    }

    fn with_stride(
        s: &'a Signals,
        w: &[f64; 6],
        base: &[Column<'a>],
        target: Option<&'a [[f64; 6]]>,
        folds: usize,
        stride: usize,
    ) -> Self {
        Self::with_pieces(s, w, base, target, folds, stride, None)
    }

    fn with_pieces(
        s: &'a Signals,
        w: &[f64; 6],
        base: &[Column<'a>],
        target: Option<&'a [[f64; 6]]>,
        folds: usize,
        stride: usize,
        given: Option<Vec<(usize, usize)>>,
    ) -> Self {
        let n = s.len();
        let target = target.unwrap_or(s.target());
        let base: Vec<Column<'a>> = base.to_vec();
        let folds = folds.max(1);
        let mut pieces = Vec::new();
        if let Some(g) = given {
            pieces = g;
        } else if folds == 1 {
            pieces.push((0, n));
        } else {
            // Blocks of at least MIN_BLOCK_SECONDS, dealt to the folds in turn (fold of block b:
            // b mod folds), so that every fold holds out several parts of a long flight and
            // trains on the others: an effect present in one part of the flight only (near the
            // ground, at speed) is still learnt from the folds that hold out another part.
            let dt = s.mean_dt().max(1e-9);
            let duration = dt * n as f64;
            let rounds = ((duration / (folds as f64 * MIN_BLOCK_SECONDS)).floor() as usize)
                .clamp(1, MAX_BLOCK_ROUNDS);
            let blocks = folds * rounds;
            let buffer = ((1.0 / dt).round() as usize).min(n / (4 * blocks)).max(1);
            for b in 0..blocks {
                let lo = b * n / blocks;
                let hi = (b + 1) * n / blocks;
                pieces.push((lo, lo + buffer));
                pieces.push((lo + buffer, hi - buffer));
                pieces.push((hi - buffer, hi));
            }
        }
        let mut all: Vec<Column<'_>> = vec![Column::Target];
        all.extend(base.iter().copied());
        let weights = vec![*w; 1 + base.len()];
        let support = Support::of_all(&all);
        let refs: Vec<&Support> = support.iter().collect();
        let base_gram = cross_tensor(
            s,
            target,
            (&all, &refs),
            &weights,
            (&all, &refs),
            &weights,
            &pieces,
            stride,
        );
        Self {
            s,
            w: *w,
            target,
            base,
            pieces,
            folds,
            base_gram,
            stride,
            support,
        }
    }

    /// The same base and target for a scan: no folds (in-sample SSE only) and every
    /// `n / SCAN_SAMPLES`-th sample.
    pub fn for_scan(&self) -> GramEngine<'a> {
        let n = self.s.len();
        let stride = (n / SCAN_SAMPLES).max(1);
        let pieces = vec![(0, n)];
        let mut all: Vec<Column<'_>> = vec![Column::Target];
        all.extend(self.base.iter().copied());
        let weights = vec![self.w; 1 + self.base.len()];
        let refs: Vec<&Support> = self.support.iter().collect();
        let base_gram = cross_tensor(
            self.s,
            self.target,
            (&all, &refs),
            &weights,
            (&all, &refs),
            &weights,
            &pieces,
            stride,
        );
        GramEngine {
            s: self.s,
            w: self.w,
            target: self.target,
            base: self.base.clone(),
            pieces,
            folds: 1,
            base_gram,
            stride,
            support: self.support.clone(),
        }
    }

    /// Evaluates base + `cand` (unweighted extra columns; may be empty).
    pub fn evaluate(&self, cand: &[ColData]) -> Evaluation {
        self.evaluate_with(cand, None)
    }

    /// Evaluates base + `cand` with the known part `offset` (unweighted; fixed columns times
    /// their values) moved to the target: the target becomes `y − offset`.
    pub fn evaluate_with<C: Borrow<ColData>>(
        &self,
        cand: &[C],
        offset: Option<&ColData>,
    ) -> Evaluation {
        let cand: Vec<Column<'_>> = cand.iter().map(|c| Column::Stored(c.borrow())).collect();
        self.evaluate_columns(&cand, offset.map(Column::Stored))
    }

    /// [`Self::evaluate_with`] for candidate columns and offset given at the samples this
    /// engine reads only, `0, stride, 2 stride, …` ([`Self::stride`];
    /// [`crate::fit::design::sampled_effect_design`]): the same bits as from the full columns.
    /// For engines without folds ([`Self::for_scan`], [`Self::new_for_scan`]).
    pub fn evaluate_sampled(&self, cand: &[ColData], offset: Option<&ColData>) -> Evaluation {
        assert_eq!(
            self.pieces,
            [(0, self.s.len())],
            "sampled columns need one piece"
        );
        let cand: Vec<Column<'_>> = cand.iter().map(Column::Sampled).collect();
        self.evaluate_columns(&cand, offset.map(Column::Sampled))
    }

    /// [`Self::evaluate_with`] for candidate columns and offset given at this engine's samples
    /// [`Self::span`] only (each vector holds the span's values,
    /// [`crate::fit::design::window_effect_design`]): the same bits as from the full columns.
    pub fn evaluate_window(&self, cand: &[ColData], offset: Option<&ColData>) -> Evaluation {
        let start = self.span().start;
        let cand: Vec<Column<'_>> = cand.iter().map(|c| Column::Window(c, start)).collect();
        self.evaluate_columns(&cand, offset.map(|o| Column::Window(o, start)))
    }

    /// Every `stride`-th sample enters this engine's cross products.
    pub fn stride(&self) -> usize {
        self.stride
    }

    fn evaluate_columns(&self, candr: &[Column<'_>], offset: Option<Column<'_>>) -> Evaluation {
        let p0 = 1 + self.base.len();
        let q = candr.len();
        let pp = p0 + q;
        let np = self.pieces.len();
        let mut left: Vec<Column<'_>> = vec![Column::Target];
        left.extend(self.base.iter().copied());
        left.extend(candr.iter().copied());
        let wl = vec![self.w; pp];
        let wc = vec![self.w; q];
        let (s, t) = (self.s, self.target);
        let cand_support = Support::of_all(candr);
        let cand_refs: Vec<&Support> = cand_support.iter().collect();
        let left_refs: Vec<&Support> = self.support.iter().chain(&cand_support).collect();
        let (l, c) = ((&left[..], &left_refs[..]), (candr, &cand_refs[..]));
        let (pieces, stride) = (&self.pieces, self.stride);
        let cross = cross_tensor(s, t, l, &wl, c, &wc, pieces, stride);
        // The offset's cross products with [y, base…, cand…] and with itself.
        let wo = [self.w];
        let (ocross, oo) = match offset {
            Some(o) => {
                let o = [o];
                let os = Support::of(&o[0]);
                let os = [&os];
                let o = (&o[..], &os[..]);
                (
                    cross_tensor(s, t, o, &wo, l, &wl, pieces, stride),
                    cross_tensor(s, t, o, &wo, o, &wo, pieces, stride),
                )
            }
            None => (Vec::new(), Vec::new()),
        };
        // Assemble the full (pp × pp) matrices per piece and channel.
        let mut g = vec![0.0; np * 6 * pp * pp];
        for pc in 0..np * 6 {
            let dst = &mut g[pc * pp * pp..(pc + 1) * pp * pp];
            let src = &self.base_gram[pc * p0 * p0..(pc + 1) * p0 * p0];
            for i in 0..p0 {
                for j in 0..p0 {
                    dst[i * pp + j] = src[i * p0 + j];
                }
            }
            let cs = &cross[pc * pp * q..(pc + 1) * pp * q];
            for i in 0..pp {
                for j in 0..q {
                    dst[i * pp + p0 + j] = cs[i * q + j];
                    dst[(p0 + j) * pp + i] = cs[i * q + j];
                }
            }
            if offset.is_some() {
                // y → y − o: (y−o)ᵀ(y−o) = yᵀy − 2 oᵀy + oᵀo; (y−o)ᵀx = yᵀx − oᵀx.
                let oc = &ocross[pc * pp..(pc + 1) * pp];
                dst[0] += -2.0 * oc[0] + oo[pc];
                for j in 1..pp {
                    dst[j] -= oc[j];
                    dst[j * pp] -= oc[j];
                }
            }
        }
        let sum_pieces = |sel: &dyn Fn(usize) -> bool, ch: Option<usize>| -> Vec<f64> {
            let mut out = vec![0.0; pp * pp];
            for pi in 0..np {
                if !sel(pi) {
                    continue;
                }
                for c in 0..6 {
                    if ch.is_some_and(|x| x != c) {
                        continue;
                    }
                    let m = &g[(pi * 6 + c) * pp * pp..(pi * 6 + c + 1) * pp * pp];
                    for (o, x) in out.iter_mut().zip(m) {
                        *o += x;
                    }
                }
            }
            out
        };
        let total = sum_pieces(&|_| true, None);
        let (beta, cov_diag) = solve_gram(&total, pp);
        let gram_diag: Vec<f64> = (1..pp).map(|j| total[j * pp + j]).collect();
        let mut gram_diag_ch = vec![[0.0; 6]; pp - 1];
        for pi in 0..np {
            for c in 0..6 {
                let m = &g[(pi * 6 + c) * pp * pp..(pi * 6 + c + 1) * pp * pp];
                for (j, d) in gram_diag_ch.iter_mut().enumerate() {
                    d[c] += m[(j + 1) * pp + j + 1];
                }
            }
        }
        let sse_full = sse_of(&total, pp, &beta);
        let sse_full_ch: [f64; 6] =
            std::array::from_fn(|c| sse_of(&sum_pieces(&|_| true, Some(c)), pp, &beta));
        let mut sse_cv_ch = [0.0; 6];
        let mut fold_beta = Vec::new();
        if self.folds > 1 {
            let blocks = np / 3;
            let folds = self.folds;
            let k_of = |pi: usize| (pi / 3) % folds;
            for k in 0..self.folds {
                // The fold's blocks, and the buffers of their neighbours on the near side.
                let excluded = |pi: usize| {
                    let (b, part) = (pi / 3, pi % 3);
                    k_of(pi) == k
                        || (part == 2 && b + 1 < blocks && (b + 1) % folds == k)
                        || (part == 0 && b > 0 && (b - 1) % folds == k)
                };
                let train = sum_pieces(&|pi| !excluded(pi), None);
                let bk = solve_fold(&train, &total, &beta, pp);
                for c in 0..6 {
                    let test = sum_pieces(&|pi| k_of(pi) == k, Some(c));
                    let e = sse_of(&test, pp, &bk);
                    sse_cv_ch[c] += e;
                }
                fold_beta.push(bk);
            }
        } else {
            // Without folds the held-out error is the in-sample one.
            sse_cv_ch = sse_full_ch;
        }
        Evaluation {
            sse_full,
            sse_full_ch,
            sse_cv_ch,
            beta,
            cov_diag,
            gram_diag,
            gram_diag_ch,
            fold_beta,
        }
    }

    /// The sample ranges the cross-validation holds out, each with its fold (one range, the
    /// whole log, in fold 0 without folds).
    pub fn fold_ranges(&self) -> Vec<(std::ops::Range<usize>, usize)> {
        if self.folds <= 1 {
            return vec![(0..self.s.len(), 0)];
        }
        (0..self.pieces.len() / 3)
            .map(|b| {
                (
                    self.pieces[3 * b].0..self.pieces[3 * b + 2].1,
                    b % self.folds,
                )
            })
            .collect()
    }

    /// The held-out residual series of base + `cand` (with the known part `offset`), in the
    /// target's units (unweighted): each sample predicted with the coefficients of the fold
    /// that holds it out ([`Evaluation::fold_beta`] of `ev`, from
    /// [`Self::evaluate_with`] of the same columns); without folds, the in-sample residual at
    /// `ev.beta`. What a model's held-out error is judged on when it is not a sum of
    /// squares of the target (a filter of the residual, its whiteness).
    ///
    /// Columns marked in `nuisance` (base then candidate; a shorter mask is padded with
    /// `false`) keep their all-data coefficient: a start-of-log transient is an initial
    /// condition, reproduced in every fold, never predicted. Other directions the fold's
    /// training samples cannot determine keep their all-data value too (see `solve_fold`).
    pub fn held_out_residual<C: Borrow<ColData>>(
        &self,
        cand: &[C],
        offset: Option<&ColData>,
        ev: &Evaluation,
        nuisance: &[bool],
    ) -> Vec<[f64; 6]> {
        let n = self.s.len();
        let mut r: Vec<[f64; 6]> = self.target.to_vec();
        if let Some(o) = offset {
            for (c, d) in o.iter().enumerate() {
                if let Some(v) = d {
                    for (ri, x) in r.iter_mut().zip(v) {
                        ri[c] -= x;
                    }
                }
            }
        }
        let ranges = self.fold_ranges();
        let betas: Vec<Vec<f64>> = if ev.fold_beta.len() == self.folds && self.folds > 1 {
            ev.fold_beta
                .iter()
                .map(|bk| {
                    bk.iter()
                        .enumerate()
                        .map(|(j, b)| {
                            if nuisance.get(j).copied().unwrap_or(false) {
                                ev.beta[j]
                            } else {
                                *b
                            }
                        })
                        .collect()
                })
                .collect()
        } else {
            vec![ev.beta.clone(); self.folds.max(1)]
        };
        let nb = self.base.len();
        let mut blocks = Blocks::new(self.s, None);
        blocks.need(&self.base);
        for (range, fold) in ranges {
            let beta = &betas[fold];
            for_each_block(&mut blocks, range.clone(), |blk, lo, hi| {
                subtract_base(blk, &self.base, beta, &[1.0; 6], &mut r[lo..hi]);
            });
            for (col, &b) in cand.iter().zip(&beta[nb.min(beta.len())..]) {
                for (c, d) in col.borrow().iter().enumerate() {
                    if let Some(v) = d {
                        for i in range.clone() {
                            r[i][c] -= b * v[i];
                        }
                    }
                }
            }
        }
        debug_assert_eq!(r.len(), n);
        r
    }

    /// [`Self::residual`] in the target's units: each channel divided by its weight.
    pub fn residual_unweighted<C: Borrow<ColData>>(
        &self,
        cand: &[C],
        offset: Option<&ColData>,
        beta: &[f64],
    ) -> Vec<[f64; 6]> {
        let mut r = self.residual(cand, offset, beta);
        self.unweight(&mut r);
        r
    }

    /// [`Self::residual_unweighted`] for columns given at the samples [`Self::span`] only (as
    /// to [`Self::evaluate_window`]).
    pub fn residual_window_unweighted(
        &self,
        cand: &[ColData],
        offset: Option<&ColData>,
        beta: &[f64],
    ) -> Vec<[f64; 6]> {
        let mut r = self.residual_from(cand, offset, beta, 0);
        self.unweight(&mut r);
        r
    }

    /// Divides each channel of a weighted residual by its weight.
    fn unweight(&self, r: &mut [[f64; 6]]) {
        for x in r.iter_mut() {
            for c in 0..6 {
                x[c] /= self.w[c];
            }
        }
    }

    /// Weighted residual of base + `cand` (with the known part `offset`) at coefficients
    /// `beta` (from [`Self::evaluate_with`]).
    pub fn residual<C: Borrow<ColData>>(
        &self,
        cand: &[C],
        offset: Option<&ColData>,
        beta: &[f64],
    ) -> Vec<[f64; 6]> {
        self.residual_from(cand, offset, beta, self.span().start)
    }

    /// [`Self::residual`] over [`Self::span`], the columns' and the offset's vectors read from
    /// index `first` for the span's first sample (its own index for full columns, 0 for
    /// columns given on the span only).
    fn residual_from<C: Borrow<ColData>>(
        &self,
        cand: &[C],
        offset: Option<&ColData>,
        beta: &[f64],
        first: usize,
    ) -> Vec<[f64; 6]> {
        let span = self.span();
        let (lo0, hi0) = (span.start, span.end);
        let (f0, f1) = (first, first + (hi0 - lo0));
        let mut r: Vec<[f64; 6]> = self.target[lo0..hi0]
            .iter()
            .map(|t| std::array::from_fn(|c| t[c] * self.w[c]))
            .collect();
        if let Some(o) = offset {
            for (c, d) in o.iter().enumerate() {
                if let Some(v) = d {
                    for (ri, x) in r.iter_mut().zip(&v[f0..f1]) {
                        ri[c] -= x * self.w[c];
                    }
                }
            }
        }
        // The base columns block by block (the rigid-body ones computed per block), in
        // column order per sample as over whole columns.
        let mut blocks = Blocks::new(self.s, None);
        blocks.need(&self.base);
        let w = self.w;
        for_each_block(&mut blocks, span.clone(), |blk, lo, hi| {
            subtract_base(blk, &self.base, beta, &w, &mut r[lo - lo0..hi - lo0]);
        });
        for (col, &b) in cand.iter().zip(&beta[self.base.len().min(beta.len())..]) {
            for (c, d) in col.borrow().iter().enumerate() {
                if let Some(v) = d {
                    for (ri, x) in r.iter_mut().zip(&v[f0..f1]) {
                        ri[c] -= b * (x * self.w[c]);
                    }
                }
            }
        }
        r
    }
}

/// Subtracts `b_j (x_j w)` of each column `x_j` of `base` (coefficient `b_j` of `beta`, channel
/// weights `w`) from the rows `r` of the loaded block `blk`, column after column on each value
/// (the same order as column by column over the rows). Per channel through one contiguous
/// buffer, so the subtractions run over adjacent values.
fn subtract_base(
    blk: &Blocks<'_>,
    base: &[Column<'_>],
    beta: &[f64],
    w: &[f64; 6],
    r: &mut [[f64; 6]],
) {
    let mut buf = [0.0; BLOCK_SAMPLES];
    for c in 0..6 {
        let cols: Vec<(&[f64], f64)> = base
            .iter()
            .zip(beta)
            .filter_map(|(col, &b)| blk.get(col, c).map(|(v, _)| (v, b)))
            .collect();
        if cols.is_empty() {
            continue;
        }
        let buf = &mut buf[..r.len()];
        for (x, ri) in buf.iter_mut().zip(r.iter()) {
            *x = ri[c];
        }
        for (v, b) in cols {
            for (x, y) in buf.iter_mut().zip(v) {
                *x -= b * (y * w[c]);
            }
        }
        for (ri, x) in r.iter_mut().zip(buf.iter()) {
            ri[c] = *x;
        }
    }
}

/// Adds `Σ (x_i fx)(y_i fy)` to four interleaved partial sums `acc` (so the compiler can
/// keep four products in flight), the samples past the last multiple of 4 to `tail`; the
/// dot product is `(acc₀ + acc₁) + (acc₂ + acc₃) + tail`. Fed consecutive blocks whose
/// lengths are multiples of 4 (all but the last), the sums are those over the whole series:
/// the order is fixed, so results are reproducible.
fn dot_accumulate(x: &[f64], fx: f64, y: &[f64], fy: f64, acc: &mut [f64; 4], tail: &mut f64) {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let mut xs = x.chunks_exact(4);
    let mut ys = y.chunks_exact(4);
    for (a, b) in (&mut xs).zip(&mut ys) {
        acc[0] += (a[0] * fx) * (b[0] * fy);
        acc[1] += (a[1] * fx) * (b[1] * fy);
        acc[2] += (a[2] * fx) * (b[2] * fy);
        acc[3] += (a[3] * fx) * (b[3] * fy);
    }
    for (a, b) in xs.remainder().iter().zip(ys.remainder()) {
        *tail += (a * fx) * (b * fy);
    }
}

/// [`dot_accumulate`] of the samples `from..to` of a block only (`x`, `y` the whole block):
/// each sample into the partial sum it takes over the whole block, in the same order. Where
/// the other samples' products are zero (one factor 0, the other finite) the sums are those
/// of [`dot_accumulate`] bit for bit: a partial sum starts at `+0` and so is never `−0`,
/// and `s + (±0) = s` for any other `s`.
#[allow(clippy::too_many_arguments)]
fn dot_accumulate_range(
    x: &[f64],
    fx: f64,
    y: &[f64],
    fy: f64,
    acc: &mut [f64; 4],
    tail: &mut f64,
    from: usize,
    to: usize,
) {
    let n = x.len().min(y.len());
    let chunked = n - n % 4;
    for i in from..to.min(n) {
        let t = (x[i] * fx) * (y[i] * fy);
        if i < chunked {
            acc[i % 4] += t;
        } else {
            *tail += t;
        }
    }
}

/// Per channel of a column, the samples outside of which its values are zero (`None`: a
/// column that is not stored, or no values on the channel; every sample counts), and whether
/// they are finite there (checked once, when a product first asks). A motor lag's
/// start-of-log columns are zero after their transient: their cross products need only its
/// first samples ([`cross_tensor`]).
#[derive(Debug, Clone, Default)]
struct Support {
    ranges: [Option<std::ops::Range<usize>>; 6],
    finite: [std::sync::OnceLock<bool>; 6],
}

impl Support {
    /// The support of `col` (its values scanned once).
    fn of(col: &Column<'_>) -> Self {
        let mut out = Self::default();
        let (d, start) = match col {
            Column::Stored(d) => (d, 0),
            Column::Window(d, start) => (d, *start),
            _ => return out,
        };
        for (r, v) in out.ranges.iter_mut().zip(d.iter()) {
            *r = v.as_deref().map(|v| {
                let r = nonzero_range(v);
                r.start + start..r.end + start
            });
        }
        out
    }

    /// The supports of `cols`.
    fn of_all(cols: &[Column<'_>]) -> Vec<Self> {
        cols.iter().map(Self::of).collect()
    }

    /// `true` unless `col` (the column this support was made of) has a non-finite value on
    /// channel `c` within its support.
    fn finite(&self, col: &Column<'_>, c: usize) -> bool {
        *self.finite[c].get_or_init(|| match (col, &self.ranges[c]) {
            (Column::Stored(d), Some(r)) => d[c].as_ref().is_none_or(|v| {
                v[r.clone()]
                    .chunks(SCAN_CHUNK)
                    .all(|x| x.iter().fold(true, |a, y| a & y.is_finite()))
            }),
            (Column::Window(d, start), Some(r)) => d[c].as_ref().is_none_or(|v| {
                v[r.start - start..r.end - start]
                    .chunks(SCAN_CHUNK)
                    .all(|x| x.iter().fold(true, |a, y| a & y.is_finite()))
            }),
            _ => true,
        })
    }
}

/// Values tested together when a column is scanned for its support (a vectorised test per
/// chunk instead of a branch per value).
const SCAN_CHUNK: usize = 16;

/// The samples from the first to the last value of `v` that is not zero (`0..0` if none; a
/// NaN counts as not zero).
fn nonzero_range(v: &[f64]) -> std::ops::Range<usize> {
    let any = |x: &[f64]| x.iter().fold(false, |a, y| a | (*y != 0.0));
    let (Some(first), Some(last)) = (
        v.chunks(SCAN_CHUNK).position(any),
        v.chunks(SCAN_CHUNK).rposition(any),
    ) else {
        return 0..0;
    };
    let (a, b) = (first * SCAN_CHUNK, last * SCAN_CHUNK);
    let lo = a + v[a..].iter().position(|y| *y != 0.0).unwrap_or(0);
    let hi = b + v[b..(b + SCAN_CHUNK).min(v.len())]
        .iter()
        .rposition(|y| *y != 0.0)
        .map_or(0, |i| i + 1);
    lo..hi
}

/// Cross products `Σ_{i ∈ piece} (a_j[c][i] wa_j[c]) (b_k[c][i] wb_k[c])` (unweighted
/// operands, per-operand, per-channel weights `wa`, `wb`) for every piece,
/// channel, `j`, `k`; layout `[piece][channel][j][k]`. Every `stride`-th sample of a piece
/// enters (summed in sample order); with stride 1, four interleaved partial sums
/// ([`dot_accumulate`]). The samples are read block by block ([`Blocks`]): the rigid-body
/// columns are computed once per block for every product that needs them. With stride 1, a
/// product with a stored column that is zero outside a range of samples ([`support`]) sums
/// that range only ([`dot_accumulate_range`]): the same bits, the other operands being
/// finite (a validated log's signals and target are).
/// `sa`, `sb`: the supports of `a` and `b` ([`Support::of_all`]).
#[allow(clippy::too_many_arguments)]
fn cross_tensor(
    s: &Signals,
    target: &[[f64; 6]],
    (a, sa): (&[Column<'_>], &[&Support]),
    wa: &[[f64; 6]],
    (b, sb): (&[Column<'_>], &[&Support]),
    wb: &[[f64; 6]],
    pieces: &[(usize, usize)],
    stride: usize,
) -> Vec<f64> {
    let (pa, pb) = (a.len(), b.len());
    let mut out = vec![0.0; pieces.len() * 6 * pa * pb];
    // The Gram of a set with itself is symmetric: the upper triangle is mirrored.
    let symmetric = pa == pb && a.iter().zip(b).all(|(x, y)| x.same(y));
    let mut pairs: Vec<(usize, usize, usize)> = Vec::new();
    for (j, aj) in a.iter().enumerate() {
        for (k, bk) in b.iter().enumerate() {
            if symmetric && k < j {
                continue;
            }
            for c in 0..6 {
                if aj.has(c) && bk.has(c) {
                    pairs.push((j, k, c));
                }
            }
        }
    }
    if pairs.is_empty() {
        return out;
    }
    let mut blocks = Blocks::new(s, Some(target));
    blocks.need(a);
    blocks.need(b);
    // Per pair, the samples where its products can be non-zero (`None`: all of them). Only
    // where both operands are finite (the products outside are then ±0): the stored ones are
    // checked (once per column and channel, when a product would skip samples), the
    // target's and the rigid-body columns' are finite on a validated log.
    let ranges: Vec<Option<std::ops::Range<usize>>> = if stride == 1 {
        let first = pieces.iter().map(|p| p.0).min().unwrap_or(0);
        let last = pieces.iter().map(|p| p.1).max().unwrap_or(0);
        pairs
            .iter()
            .map(|&(j, k, c)| {
                let range = match (&sa[j].ranges[c], &sb[k].ranges[c]) {
                    (None, None) => return None,
                    (Some(r), None) | (None, Some(r)) => r.clone(),
                    (Some(r), Some(q)) => r.start.max(q.start)..r.end.min(q.end),
                };
                if range.start <= first && range.end >= last {
                    // Every sample of the pieces counts.
                    return None;
                }
                let finite = wa[j][c].is_finite()
                    && wb[k][c].is_finite()
                    && sa[j].finite(&a[j], c)
                    && sb[k].finite(&b[k], c);
                finite.then_some(range)
            })
            .collect()
    } else {
        vec![None; pairs.len()]
    };
    let mut acc = vec![[0.0f64; 4]; pairs.len()];
    let mut tail = vec![0.0f64; pairs.len()];
    let mut sums = vec![0.0f64; pairs.len()];
    for (pi, &(lo, hi)) in pieces.iter().enumerate() {
        acc.iter_mut().for_each(|x| *x = [0.0; 4]);
        tail.iter_mut().for_each(|x| *x = 0.0);
        let mut first = true;
        let mut blo = lo;
        while blo < hi {
            let bhi = (blo + BLOCK_SAMPLES * stride).min(hi);
            blocks.load(blo, bhi, stride);
            for (q, &(j, k, c)) in pairs.iter().enumerate() {
                let (Some((x, sx)), Some((y, sy))) = (blocks.get(&a[j], c), blocks.get(&b[k], c))
                else {
                    continue;
                };
                let (fx, fy) = (wa[j][c], wb[k][c]);
                if stride == 1 {
                    match &ranges[q] {
                        Some(r) if r.start > blo || r.end < bhi => {
                            let from = r.start.max(blo) - blo;
                            let to = r.end.min(bhi).saturating_sub(blo);
                            if from < to {
                                dot_accumulate_range(
                                    x,
                                    fx,
                                    y,
                                    fy,
                                    &mut acc[q],
                                    &mut tail[q],
                                    from,
                                    to,
                                );
                            }
                        }
                        _ => dot_accumulate(x, fx, y, fy, &mut acc[q], &mut tail[q]),
                    }
                } else {
                    let terms = x
                        .iter()
                        .step_by(sx)
                        .zip(y.iter().step_by(sy))
                        .map(|(u, v)| (u * fx) * (v * fy));
                    // In sample order across the blocks, as one sum over the piece.
                    sums[q] = if first {
                        terms.sum()
                    } else {
                        terms.fold(sums[q], |acc, t| acc + t)
                    };
                }
            }
            first = false;
            blo = bhi;
        }
        for (q, &(j, k, c)) in pairs.iter().enumerate() {
            let v = if stride == 1 {
                (acc[q][0] + acc[q][1]) + (acc[q][2] + acc[q][3]) + tail[q]
            } else if first {
                std::iter::empty::<f64>().sum()
            } else {
                sums[q]
            };
            out[((pi * 6 + c) * pa + j) * pb + k] = v;
            if symmetric {
                out[((pi * 6 + c) * pa + k) * pb + j] = v;
            }
        }
    }
    out
}

/// Solves the normal equations of a Gram matrix laid out as `[y, x…]²`: returns β for the
/// `x` part (pseudo-inverse via a symmetric eigendecomposition of the equilibrated matrix,
/// eigenvalues below 1e-12 of the largest dropped).
fn solve_gram(gm: &[f64], pp: usize) -> (Vec<f64>, Vec<f64>) {
    let p = pp - 1;
    let mut d = vec![0.0; p];
    for j in 0..p {
        let g = gm[(j + 1) * pp + j + 1];
        d[j] = if g > 0.0 { 1.0 / g.sqrt() } else { 0.0 };
    }
    let a = DMatrix::<f64>::from_fn(p, p, |i, j| gm[(i + 1) * pp + j + 1] * d[i] * d[j]);
    let rhs = DVector::<f64>::from_fn(p, |i, _| gm[(i + 1) * pp] * d[i]);
    let eig = a.symmetric_eigen();
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |m, x| m.max(*x));
    let mut x = DVector::<f64>::zeros(p);
    let mut diag = vec![0.0; p];
    for k in 0..p {
        let l = eig.eigenvalues[k];
        let v = eig.eigenvectors.column(k);
        if l > lmax * 1e-12 && l > 0.0 {
            x += v * (v.dot(&rhs) / l);
            for j in 0..p {
                diag[j] += v[j] * v[j] / l;
            }
        } else {
            for j in 0..p {
                if v[j] * v[j] > 1e-6 {
                    diag[j] = f64::INFINITY;
                }
            }
        }
    }
    (
        (0..p).map(|j| x[j] * d[j]).collect(),
        (0..p).map(|j| diag[j] * d[j] * d[j]).collect(),
    )
}

/// The share of a direction's information that a fold's training samples must hold for the
/// fold to predict along it ([`solve_fold`]): 5 %. Below it, the held-out samples carry 95 %
/// or more of what the data know about that direction.
const FOLD_INFORMATION_SHARE: f64 = 0.05;

/// The coefficients a fold's training samples give (Gram matrix `train`, laid out as
/// [`solve_gram`]'s), conditional on the all-data fit `beta` of `total` (the Gram matrix of
/// all the samples) where the training samples cannot determine them.
///
/// The directions are those of the generalised eigenproblem `train v = λ total v`: λ is the
/// share of a direction's information held by the training samples. Along a direction with
/// λ ≥ [`FOLD_INFORMATION_SHARE`] the training samples decide. Along the others (a start-of-log
/// transient, a motion flown only in the held-out block) the coefficients keep the all-data
/// fit's values, given what the training samples decide. That is the mean of the all-data
/// fit's Gaussian (precision `total`), conditional on the decided directions. Such a direction is not
/// predicted: it is reproduced, in every model alike. Solving it from a few per cent of the
/// information would extrapolate it arbitrarily far instead.
fn solve_fold(train: &[f64], total: &[f64], beta: &[f64], pp: usize) -> Vec<f64> {
    let p = pp - 1;
    let d: Vec<f64> = (0..p)
        .map(|j| {
            let g = total[(j + 1) * pp + j + 1];
            if g > 0.0 { 1.0 / g.sqrt() } else { 0.0 }
        })
        .collect();
    let scaled =
        |gm: &[f64]| DMatrix::<f64>::from_fn(p, p, |i, j| gm[(i + 1) * pp + j + 1] * d[i] * d[j]);
    let (a, b) = (scaled(total), scaled(train));
    let eig = a.symmetric_eigen();
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |m, x| m.max(*x));
    // W: the all-data matrix's range, whitened (Wᵀ A W = 1).
    let kept: Vec<usize> = (0..p)
        .filter(|&k| eig.eigenvalues[k] > lmax * 1e-12 && eig.eigenvalues[k] > 0.0)
        .collect();
    if kept.is_empty() {
        return beta.to_vec();
    }
    let w = DMatrix::<f64>::from_fn(p, kept.len(), |i, k| {
        eig.eigenvectors[(i, kept[k])] / eig.eigenvalues[kept[k]].sqrt()
    });
    let c = w.transpose() * &b * &w;
    let ceig = c.symmetric_eigen();
    // Start from the all-data coefficients (scaled), and let the training samples move them
    // along the directions they determine: there they satisfy the training normal equations.
    let mut x = DVector::<f64>::from_fn(p, |j, _| if d[j] > 0.0 { beta[j] / d[j] } else { 0.0 });
    let rhs = DVector::<f64>::from_fn(p, |i, _| train[(i + 1) * pp] * d[i]);
    let r = rhs - &b * &x;
    for k in 0..kept.len() {
        let l = ceig.eigenvalues[k];
        if l >= FOLD_INFORMATION_SHARE {
            let v = &w * ceig.eigenvectors.column(k);
            x += &v * (v.dot(&r) / l);
        }
    }
    (0..p).map(|j| x[j] * d[j]).collect()
}

/// `yᵀy − 2 βᵀ g + βᵀ G β` from a `[y, x…]²` Gram matrix.
fn sse_of(gm: &[f64], pp: usize, beta: &[f64]) -> f64 {
    let p = pp - 1;
    let mut s = gm[0];
    for i in 0..p {
        s -= 2.0 * beta[i] * gm[(i + 1) * pp];
        for j in 0..p {
            s += beta[i] * beta[j] * gm[(i + 1) * pp + j + 1];
        }
    }
    s.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testdata::{crazyflie, synthetic_log};

    /// A column zero but on `range` of channels 2 and 3 (values that vary from sample to sample).
    fn sparse(n: usize, range: std::ops::Range<usize>, scale: f64) -> ColData {
        let mut v = vec![0.0; n];
        for i in range {
            v[i] = scale * ((i as f64) * 0.37).sin();
        }
        let mut d: ColData = Default::default();
        d[2] = Some(v.clone());
        d[3] = Some(v.iter().map(|x| -x).collect());
        d
    }

    /// The Gram products of columns zero outside a few samples, summed over their supports
    /// only, have the bits of the full sums (every sample, as without a support): with
    /// folds, in a window, at the start, in the middle and at the end of the log, on a log
    /// of several blocks whose length is no multiple of 4.
    #[test]
    fn products_over_supports_equal_full_sums_bit_for_bit() {
        let log = synthetic_log(&crazyflie(), 5_003, 5e-3, 11, &|_, vb| {
            [-0.02 * vb.x, -0.01 * vb.y, 0.0, 0.0, 0.0, 0.0]
        });
        let s = Signals::from_log(&log).unwrap();
        let n = s.len();
        let dense = crate::fit::effect_design(
            crate::effects::builtin(crate::EffectKind::LinearDrag)
                .unwrap()
                .as_ref(),
            &s,
            None,
        )
        .cols;
        let cols = [
            sparse(n, 0..29, 0.3),
            sparse(n, 1021..1031, 2.0),
            sparse(n, n - 7..n, 0.5),
            sparse(n, 0..0, 1.0),
            dense[0].clone(),
        ];
        let mut all: Vec<Column<'_>> = vec![Column::Target];
        all.extend((0..10).map(Column::Rigid));
        all.extend(cols.iter().map(Column::Stored));
        let w = vec![[100.0, 100.0, 50.0, 1e5, 1e5, 1e5]; all.len()];
        let real = Support::of_all(&all);
        let none = vec![Support::default(); all.len()];
        let (real, none): (Vec<&Support>, Vec<&Support>) =
            (real.iter().collect(), none.iter().collect());
        let folds = GramEngine::new(&s, &w[0], &[], None, 5).pieces;
        for pieces in [vec![(0, n)], folds, vec![(1000, 2003)], vec![(3, n - 5)]] {
            let with = cross_tensor(
                &s,
                s.target(),
                (&all, &real),
                &w,
                (&all, &real),
                &w,
                &pieces,
                1,
            );
            let without = cross_tensor(
                &s,
                s.target(),
                (&all, &none),
                &w,
                (&all, &none),
                &w,
                &pieces,
                1,
            );
            assert!(with.iter().any(|x| *x != 0.0));
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&with), bits(&without), "pieces {pieces:?}");
        }
    }

    /// The residual subtracts the base columns as a plain loop over the samples does, bit for
    /// bit (the base columns stored, the coefficients arbitrary).
    #[test]
    fn residual_equals_a_plain_loop_bit_for_bit() {
        let log = synthetic_log(&crazyflie(), 2_501, 5e-3, 3, &|_, _| [0.0; 6]);
        let s = Signals::from_log(&log).unwrap();
        let base = crate::fit::rigid_columns(&s);
        let cols: Vec<Column<'_>> = base.iter().map(Column::Stored).collect();
        let w = [3.0, 5.0, 7.0, 1e3, 2e3, 3e3];
        let beta: Vec<f64> = (0..10).map(|j| 0.1 + 0.37 * j as f64).collect();
        let r = GramEngine::new(&s, &w, &cols, None, 1).residual::<ColData>(&[], None, &beta);
        for (i, ri) in r.iter().enumerate() {
            for c in 0..6 {
                let mut want = s.target()[i][c] * w[c];
                for (d, b) in base.iter().zip(&beta) {
                    if let Some(v) = &d[c] {
                        want -= b * (v[i] * w[c]);
                    }
                }
                assert_eq!(ri[c].to_bits(), want.to_bits(), "sample {i}, channel {c}");
            }
        }
    }

    /// The `[y, x…]²` Gram matrix of rows `(y, x)`.
    fn gram(rows: &[(f64, Vec<f64>)]) -> (Vec<f64>, usize) {
        let pp = rows[0].1.len() + 1;
        let mut g = vec![0.0; pp * pp];
        for (y, x) in rows {
            let v: Vec<f64> = std::iter::once(*y).chain(x.iter().copied()).collect();
            for i in 0..pp {
                for j in 0..pp {
                    g[i * pp + j] += v[i] * v[j];
                }
            }
        }
        (g, pp)
    }

    /// Rows of `y = 2 x₀ − x₁ + 0.5 x₂ + e` with a pseudo-random design; `x₂` is zero outside
    /// the rows `lo..hi` (a transient).
    fn rows(n: usize, lo: usize, hi: usize) -> Vec<(f64, Vec<f64>)> {
        let mut state = 12345u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        (0..n)
            .map(|i| {
                let x = vec![
                    next(),
                    next(),
                    if (lo..hi).contains(&i) { next() } else { 0.0 },
                ];
                let y = 2.0 * x[0] - x[1] + 0.5 * x[2] + 0.01 * next();
                (y, x)
            })
            .collect()
    }

    /// [`rows`]`(n, 0, transient)` held out before `first`: the all-data Gram matrix, the
    /// training one, its size, the all-data fit and the fold's.
    fn fold(
        n: usize,
        transient: usize,
        first: usize,
    ) -> (Vec<f64>, Vec<f64>, usize, Vec<f64>, Vec<f64>) {
        let all = rows(n, 0, transient);
        let (total, pp) = gram(&all);
        let (train, _) = gram(&all[first..]);
        let (beta, _) = solve_gram(&total, pp);
        let got = solve_fold(&train, &total, &beta, pp);
        (total, train, pp, beta, got)
    }

    /// A fold whose training rows hold every direction well: the plain least-squares solution
    /// of the training rows, computed independently (normal equations by Cramer's rule).
    #[test]
    fn a_well_determined_fold_is_the_training_least_squares() {
        let (_, train, pp, _, got) = fold(400, 400, 100);
        // Independent: 3×3 normal equations of the training rows by Cramer's rule.
        let a = |i: usize, j: usize| train[(i + 1) * pp + j + 1];
        let b = |i: usize| train[(i + 1) * pp];
        let det3 = |m: [[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let m: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| a(i, j)));
        let d = det3(m);
        for k in 0..3 {
            let mut mk = m;
            for (i, row) in mk.iter_mut().enumerate() {
                row[k] = b(i);
            }
            let want = det3(mk) / d;
            assert!(
                (got[k] - want).abs() < 1e-9 * want.abs().max(1.0),
                "{k}: {got:?} {want}"
            );
        }
    }

    /// A transient held out: the other columns are the training rows' least squares, and the
    /// transient's keeps the all-data fit's value given them.
    #[test]
    fn a_direction_the_training_rows_do_not_see_keeps_the_all_data_fit_given_the_rest() {
        // The fold holds rows 0..100 out: its training rows have x₂ = 0 everywhere.
        let (total, train, pp, beta, got) = fold(400, 40, 100);
        // The first two: the training rows' 2×2 least squares (x₂ = 0 there).
        let a = |i: usize, j: usize| train[(i + 1) * pp + j + 1];
        let b = |i: usize| train[(i + 1) * pp];
        let d = a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0);
        let want = [
            (b(0) * a(1, 1) - a(0, 1) * b(1)) / d,
            (a(0, 0) * b(1) - a(1, 0) * b(0)) / d,
        ];
        for k in 0..2 {
            assert!((got[k] - want[k]).abs() < 1e-9, "{k}: {got:?} {want:?}");
        }
        // x₂: the all-data fit's value given the first two, the conditional mean of a Gaussian
        // of precision `total` about `beta`: β₂ − T₂₂⁻¹ (T₂₀ δ₀ + T₂₁ δ₁).
        let t = |i: usize, j: usize| total[(i + 1) * pp + j + 1];
        let want2 =
            beta[2] - (t(2, 0) * (got[0] - beta[0]) + t(2, 1) * (got[1] - beta[1])) / t(2, 2);
        assert!(
            (got[2] - want2).abs() < 1e-9 * want2.abs(),
            "{got:?} {want2}"
        );
        // Without the transient's cross-information the value would be the all-data one.
        assert!(
            (got[2] - beta[2]).abs() < 0.2 * beta[2].abs(),
            "{got:?} {beta:?}"
        );
        // Half the transient in training (rows 20..40 of 0..40): a share of 0.5, above the
        // threshold, so the training rows decide x₂ too.
        let (_, train, _, _, got) = fold(400, 40, 20);
        const { assert!(0.5 > FOLD_INFORMATION_SHARE) };
        let (plain, _) = solve_gram(&train, pp);
        for k in 0..3 {
            assert!((got[k] - plain[k]).abs() < 1e-9, "{k}: {got:?} {plain:?}");
        }
    }
}
