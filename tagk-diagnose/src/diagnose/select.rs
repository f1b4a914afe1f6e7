//! Selection on the measured noise: candidate effects, and *sets* of them, scored jointly on
//! held-out data with every channel weighted by its own noise.
//!
//! **The score.** A model is scored by its held-out (blocked cross-validation) error of
//! predicting the **measured wrench**, channel by channel in units of that channel's noise
//! ([`crate::NoiseFloor`]): `S = Σ_c Σ_i e_{c,i}² / σ_c²`. A channel far above its noise counts
//! by how much it is above it; no channel dominates by its units, and none can veto what the
//! others show. An effect that filters the measured wrench (a motor lag) is judged on the same
//! quantity: its residual is mapped back by the inverse filter ([`crate::Effect::unfilter`]),
//! so that smoothing the wrench's own noise is not mistaken for a better fit.
//!
//! **A member of a set is kept** when, within the set:
//!
//! 1. it is significant: dropping it raises the in-sample score by more than the χ² quantile
//!    of its degrees of freedom at the family-wise level (Bonferroni over the candidates). The
//!    score is scaled by the residual's variance and its autocorrelation factor;
//! 2. it gains on held-out data at least [`MIN_GAIN`] of one channel's noise variance per
//!    sample;
//! 3. its coefficients and the rigid body stay physical;
//! 4. its scanned parameter, if any, lies inside its range;
//! 5. the data can tell it apart from the other members (variance inflation).
//!
//! **The search.** Every candidate alone; every pair and triple of the most promising ones;
//! a set is admissible when every member is kept; the admissible set with the largest
//! held-out gain is the next step of the staircase.

use std::cell::RefCell;
use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;

use crate::diagnose::DiagnoseOptions;
use crate::diagnose::NoiseFloor;
use crate::diagnose::sanity::{Limits, Violation, rigid_violation};
use crate::effects::{EffectRef, Plausibility};
use crate::fit::{
    Actuator, ColData, Column, EffectDesign, Evaluation, Fit, GramEngine, Model, NoiseModel,
    actuator_interaction, actuator_role, checked_effect_design, design_of_columns, effect_design,
    filters, is_start_nuisance, residual_score, rigid_design, sampled_effect_design,
    scan_criterion, scan_window, whitened_residual, window_effect_design,
};
use crate::signals::Signals;
use crate::stats;
use tagk_dynamics::InertialParams;

/// Smallest held-out gain a member must add to its set, as a fraction of one channel's noise
/// variance per sample (5 %). Below it an effect changes no prediction a flight-dynamics
/// model cares about, however significant it is on a long log.
pub const MIN_GAIN: f64 = 0.05;

/// Variance inflation beyond which a member that fails the significance test is reported as
/// not told apart from the others (100: its columns are 99.5 % explained by the other
/// columns), rather than as merely not significant.
pub const MAX_INFLATION: f64 = 100.0;

/// How many of the best single candidates enter pairs, and how many enter triples.
const PAIR_POOL: usize = 8;
const TRIPLE_POOL: usize = 5;

/// A member of a candidate set: an effect at a value of its scanned parameter.
#[derive(Debug, Clone)]
pub(crate) struct Member {
    /// The effect.
    pub effect: EffectRef,
    /// Its scanned parameter (`None` without a scan).
    pub param: Option<f64>,
}

impl Member {
    fn name(&self) -> &str {
        self.effect.name()
    }
}

/// The design of a fitted model: rigid columns (computed where they are read), then each
/// effect's fitted columns at its parameter.
pub(crate) struct ModelDesign {
    rigid: Vec<Column<'static>>,
    effects: Vec<ColData>,
    /// Per column (rigid first): a start-of-log nuisance column.
    nuisance: Vec<bool>,
}

impl ModelDesign {
    /// Every column, rigid body first.
    pub fn columns(&self) -> Vec<Column<'_>> {
        self.rigid
            .iter()
            .copied()
            .chain(Column::stored(&self.effects))
            .collect()
    }
}

/// How one set scores in a context: the likelihood of the measured wrench in units of each
/// channel's noise variance ([`crate::fit::residual_score`]): innovations' sums of squares
/// plus, for a filtered target, the log-determinant term.
#[derive(Debug, Clone)]
pub(crate) struct Score {
    /// Held-out score (`−2 ln p` of the held-out predictions, noise units).
    pub cv: f64,
    /// Held-out innovations' sum of squares per channel (noise units).
    pub cv_ch: [f64; 6],
    /// In-sample score (same units).
    pub fit: f64,
    /// In-sample innovations' sum of squares per channel.
    pub fit_ch: [f64; 6],
    /// Log-determinant term per channel (0 without a filter of the target).
    pub logdet: [f64; 6],
    /// Autocorrelation factor κ of the in-sample innovations (mean over the channels).
    pub kappa: f64,
    /// The same per channel.
    pub kappa_ch: [f64; 6],
    /// The coefficients: the model's columns, then the members' fitted columns.
    pub ev: Evaluation,
    /// Number of fitted columns of each member.
    pub widths: Vec<usize>,
    /// Name and unit of every member's fitted columns.
    pub names: Vec<Vec<(String, String)>>,
}

impl Score {
    /// Each channel's residual variance per sample in noise units (at least 1) times its
    /// autocorrelation factor: the scale of that channel's part of a coefficient's variance.
    pub fn channel_scales(&self, n: f64) -> [f64; 6] {
        // At least the noise itself: a residual below it (a noise-free log below its
        // resolution) does not make a coefficient known better than the noise allows.
        std::array::from_fn(|c| (self.fit_ch[c] / n.max(1.0)).max(1.0) * self.kappa_ch[c])
    }

    /// The residual scale of the channels an effect acts on (mean of their
    /// [`Self::channel_scales`]): what a scanned parameter's profile interval is measured in.
    pub fn effect_scale(&self, effect: &dyn crate::Effect, n: f64) -> f64 {
        let scales = self.channel_scales(n);
        let ch: Vec<usize> = effect.channels().into_iter().filter(|c| *c < 6).collect();
        if ch.is_empty() {
            return scales.iter().sum::<f64>() / 6.0;
        }
        ch.iter().map(|&c| scales[c]).sum::<f64>() / ch.len() as f64
    }

    /// The standard error of coefficient `j`: its variance `cov_diag_j` scaled by the
    /// residual variance of the channels that carry its information, each weighted by its
    /// share. A channel far from its noise (an unmodelled effect there) does not widen the
    /// interval of a coefficient it does not carry.
    pub fn std_error(&self, j: usize, n: f64) -> f64 {
        let scales = self.channel_scales(n);
        let info = &self.ev.gram_diag_ch[j];
        let total: f64 = info.iter().sum();
        let scale = if total > 0.0 {
            (0..6).map(|c| info[c] * scales[c]).sum::<f64>() / total
        } else {
            self.kappa * self.fit_ch.iter().sum::<f64>() / (6.0 * n.max(1.0))
        };
        (self.ev.cov_diag[j] * scale).sqrt()
    }
}

/// A model with its parameters fixed, the noise, and the target its candidates are scored on.
pub(crate) struct Context<'s> {
    pub s: &'s Signals,
    pub model: Model,
    /// Measured wrench (minus the known mass's part) minus the model's fixed columns.
    target: Vec<[f64; 6]>,
    design: ModelDesign,
    /// Channel weights `1 / σ_c`.
    pub w: [f64; 6],
    /// The two noise sources per channel, `σ_c` in total.
    noise: NoiseModel,
    pub folds: usize,
    /// The model's own filtering effects.
    filters: Vec<(EffectRef, Option<f64>)>,
    /// Effect designs computed so far, by effect name and parameter.
    designs: RefCell<DesignCache>,
    /// The model's own score ([`Context::base_with_residual`]), once computed.
    base: RefCell<Option<Score>>,
    /// The model's motor lag (its known part), composed with a candidate delay.
    model_lag: Option<Arc<ColData>>,
    /// The model's time delay \[s\], composed with a candidate lag.
    model_delay: Option<f64>,
}

/// `true` when every vector of a design (fitted columns and the fixed columns' sum) holds
/// `len` values: the length check of the columns it was made from ([`design_of_columns`]
/// keeps each vector's length).
fn design_lengths_are(d: &EffectDesign, len: usize) -> bool {
    d.cols
        .iter()
        .chain(d.offset.as_ref())
        .flat_map(|col| col.iter().flatten())
        .all(|v| v.len() == len)
}

/// Effect designs by effect name and the bits of its parameter.
type DesignCache = HashMap<(String, Option<u64>), Arc<EffectDesign>>;

impl<'s> Context<'s> {
    /// The context of `model` at its scanned parameters `params` (one per effect) on `s`,
    /// against the noise `floor`.
    pub fn new(
        s: &'s Signals,
        model: &Model,
        params: &[Option<f64>],
        floor: &NoiseFloor,
        folds: usize,
    ) -> Self {
        let (rigid, target) = rigid_design(model, s);
        let mut target = target.into_owned();
        let mut effects = Vec::new();
        let mut filt = Vec::new();
        let mut nuisance = vec![false; rigid.len()];
        let mut model_lag: Option<Arc<ColData>> = None;
        let mut model_delay: Option<f64> = None;
        for (k, e) in model.effects().iter().enumerate() {
            let p = params.get(k).copied().flatten();
            let d = effect_design(e.as_ref(), s, p);
            match actuator_role(e.as_ref()) {
                Some(Actuator::Lag) => model_lag = d.offset.clone().map(Arc::new),
                Some(Actuator::Delay) => model_delay = p,
                None => {}
            }
            nuisance.extend(d.names.iter().map(|(n, _)| is_start_nuisance(n)));
            if let Some(o) = &d.offset {
                sub(&mut target, o);
            }
            effects.extend(d.cols);
            if filters(s, e.as_ref(), p) {
                filt.push((e.clone(), p));
            }
        }
        // The model's own lag and delay compose ([`actuator_interaction`]).
        if let (Some(lag), Some(delay)) = (&model_lag, model_delay)
            && let Some(cross) = actuator_interaction(s, lag, delay)
        {
            sub(&mut target, &cross);
        }
        let sigma = floor.rms;
        let w = std::array::from_fn(|c| {
            if sigma[c] > 0.0 && sigma[c].is_finite() {
                1.0 / sigma[c]
            } else {
                1.0
            }
        });
        let noise = NoiseModel {
            wrench: floor.from_wrench,
            motion: floor.from_motion,
        }
        .scaled_to(&sigma);
        Self {
            s,
            model: model.clone(),
            target,
            design: ModelDesign {
                rigid,
                effects,
                nuisance,
            },
            w,
            noise,
            folds,
            filters: filt,
            designs: RefCell::new(HashMap::new()),
            base: RefCell::new(None),
            model_lag,
            model_delay,
        }
    }

    /// The known part that composes a lag and a delay when `members` bring one of them
    /// (the other from the members or the model; [`actuator_interaction`]), given the
    /// members' `designs`. `None` when the model holds both already, or no pair is there.
    fn member_interaction(
        &self,
        members: &[Member],
        designs: &[Arc<EffectDesign>],
    ) -> Option<ColData> {
        let mut lag: Option<&ColData> = None;
        let mut delay: Option<f64> = None;
        for (m, d) in members.iter().zip(designs) {
            match actuator_role(m.effect.as_ref()) {
                Some(Actuator::Lag) => lag = d.offset.as_ref(),
                Some(Actuator::Delay) => delay = m.param,
                None => {}
            }
        }
        if lag.is_none() && delay.is_none() {
            return None;
        }
        let lag = lag.or(self.model_lag.as_deref())?;
        actuator_interaction(self.s, lag, delay.or(self.model_delay)?)
    }

    /// `true` when `member` composes with the model's own lag or delay.
    fn composes_with_model(&self, member: &Member) -> bool {
        match actuator_role(member.effect.as_ref()) {
            Some(Actuator::Lag) => self.model_delay.is_some(),
            Some(Actuator::Delay) => self.model_lag.is_some(),
            None => false,
        }
    }

    /// The context of `model` without its `k`-th effect, the other effects at the scanned
    /// parameters of `fit` (the model's fit).
    pub fn without_effect(
        s: &'s Signals,
        model: &Model,
        fit: &Fit,
        k: usize,
        floor: &NoiseFloor,
        folds: usize,
    ) -> Self {
        let rest = model.without(model.effects()[k].name());
        Self::new(s, &rest, &fit.params_without(k), floor, folds)
    }

    /// Rigid-body columns of the design (10, or 9 with a known mass).
    pub fn rigid_columns(&self) -> usize {
        self.design.rigid.len()
    }

    /// Columns of the model's design.
    pub fn base_columns(&self) -> usize {
        self.design.rigid.len() + self.design.effects.len()
    }

    /// The engine over the model's design with the cross-validation folds.
    pub fn engine(&self) -> GramEngine<'_> {
        GramEngine::new(
            self.s,
            &self.w,
            &self.design.columns(),
            Some(&self.target),
            self.folds,
        )
    }

    /// The engine over the model's design without folds (in-sample: the scans), over the
    /// scan window of a long log ([`crate::fit::scan_window`]).
    pub fn fit_engine(&self) -> GramEngine<'_> {
        match scan_window(self.s) {
            Some(range) => GramEngine::new_window(
                self.s,
                &self.w,
                &self.design.columns(),
                Some(&self.target),
                range,
            ),
            None => GramEngine::new(
                self.s,
                &self.w,
                &self.design.columns(),
                Some(&self.target),
                1,
            ),
        }
    }

    /// The filtering effects of the model and of `members`.
    fn all_filters(&self, members: &[Member]) -> Vec<(EffectRef, Option<f64>)> {
        let mut f = self.filters.clone();
        for m in members {
            if filters(self.s, m.effect.as_ref(), m.param) {
                f.push((m.effect.clone(), m.param));
            }
        }
        f
    }

    /// An effect's design at a parameter, computed once per context (a search scores one
    /// effect in many sets).
    fn design_of(&self, m: &Member) -> Arc<EffectDesign> {
        let computed = self.cached_design(m, || {
            Ok::<_, std::convert::Infallible>(effect_design(m.effect.as_ref(), self.s, m.param))
        });
        match computed {
            Ok(d) => d,
            Err(never) => match never {},
        }
    }

    /// Checks that member `m`'s columns can enter the regression
    /// ([`crate::fit::checked_effect_design`]), keeping the design for the sets it enters.
    fn check_design(&self, m: &Member) -> Result<(), String> {
        self.cached_design(m, || {
            checked_effect_design(m.effect.as_ref(), self.s, m.param)
        })
        .map(|_| ())
    }

    /// Member `m`'s design when its columns have the log's length
    /// ([`crate::effects::check_lengths`]; `None` otherwise): the columns are computed once,
    /// for the check and the design. A kept design is checked on its own vectors, which have
    /// its columns' lengths.
    fn length_checked_design(&self, m: &Member) -> Option<Arc<EffectDesign>> {
        if let Some(d) = self.designs.borrow().get(&design_key(m)) {
            return design_lengths_are(d, self.s.len()).then(|| d.clone());
        }
        let columns = crate::effects::effect_columns(m.effect.as_ref(), self.s, m.param);
        crate::effects::check_lengths(&columns, self.s.len()).ok()?;
        let computed = self.cached_design(m, || {
            Ok::<_, std::convert::Infallible>(design_of_columns(columns, self.s))
        });
        match computed {
            Ok(d) => Some(d),
            Err(never) => match never {},
        }
    }

    /// The design of `m` from the cache, or from `compute` (kept when the log is short).
    fn cached_design<E>(
        &self,
        m: &Member,
        compute: impl FnOnce() -> Result<EffectDesign, E>,
    ) -> Result<Arc<EffectDesign>, E> {
        let key = design_key(m);
        if let Some(d) = self.designs.borrow().get(&key) {
            return Ok(d.clone());
        }
        let d = Arc::new(compute()?);
        // A long log's designs are recomputed instead of kept: a search meets dozens of them
        // (a wind's alone is 24 values a sample).
        if self.s.len() <= crate::signals::RIGID_CACHE_SAMPLES {
            self.designs.borrow_mut().insert(key, d.clone());
        }
        Ok(d)
    }

    /// The members' fitted columns, their known part, their widths and names.
    fn member_design(&self, members: &[Member]) -> MemberDesign {
        self.member_design_given(members, None)
    }

    /// [`Self::member_design`] with the design of member `k` given as `(k, design)`.
    fn member_design_given(
        &self,
        members: &[Member],
        given: Option<(usize, Arc<EffectDesign>)>,
    ) -> MemberDesign {
        let designs: Vec<Arc<EffectDesign>> = members
            .iter()
            .enumerate()
            .map(|(i, m)| match &given {
                Some((k, d)) if *k == i => d.clone(),
                _ => self.design_of(m),
            })
            .collect();
        let with_offset: Vec<&EffectDesign> = designs
            .iter()
            .map(Arc::as_ref)
            .filter(|d| d.offset.is_some())
            .collect();
        let cross = self.member_interaction(members, &designs);
        // One known part is borrowed; several are summed.
        let summed = (with_offset.len() > 1 || cross.is_some()).then(|| {
            let mut acc: ColData = Default::default();
            for d in &with_offset {
                if let Some(o) = &d.offset {
                    add_col(&mut acc, o.clone());
                }
            }
            if let Some(cross) = cross {
                add_col(&mut acc, cross);
            }
            acc
        });
        MemberDesign {
            widths: designs.iter().map(|d| d.cols.len()).collect(),
            names: designs.iter().map(|d| d.names.clone()).collect(),
            designs,
            summed,
        }
    }

    /// Scores the model plus `members` (an empty set: the model itself, scored once) with
    /// `engine` (from [`Self::engine`]).
    pub fn score(&self, engine: &GramEngine<'_>, members: &[Member]) -> Score {
        // A long log's sets without a filter are scored from the Gram matrices alone, with
        // the autocorrelation factors of the model's own residual (a residual pass per set
        // over a million samples would dominate the search).
        if self.s.len() > crate::signals::RIGID_CACHE_SAMPLES
            && self.all_filters(members).is_empty()
        {
            let mut score = self.score_light(engine, members);
            let kappa = self.base_kappa(engine);
            score.kappa_ch = kappa;
            score.kappa = kappa.iter().sum::<f64>() / 6.0;
            return score;
        }
        if members.is_empty() {
            if let Some(base) = self.base.borrow().as_ref() {
                return base.clone();
            }
            return self.base_with_residual(engine).0;
        }
        self.score_with_residual(engine, members).0
    }

    /// The autocorrelation factors of the model's own in-sample residual, computed once.
    fn base_kappa(&self, engine: &GramEngine<'_>) -> [f64; 6] {
        if let Some(base) = self.base.borrow().as_ref() {
            return base.kappa_ch;
        }
        self.base_with_residual(engine).0.kappa_ch
    }

    /// The model's own score and whitened residual ([`Self::score_with_residual`] of the empty
    /// set). The score is kept: later scores of the model reuse it. The residual is not.
    pub fn base_with_residual(&self, engine: &GramEngine<'_>) -> (Score, Vec<[f64; 6]>) {
        let (score, residual) = self.score_with_residual(engine, &[]);
        *self.base.borrow_mut() = Some(score.clone());
        (score, residual)
    }

    /// [`Self::score`] and the in-sample whitened residual (unweighted; the residual itself
    /// without a filter of the target): white with each channel's noise at the true model.
    pub fn score_with_residual(
        &self,
        engine: &GramEngine<'_>,
        members: &[Member],
    ) -> (Score, Vec<[f64; 6]>) {
        let d = self.member_design(members);
        let cols = d.cols();
        let ev = engine.evaluate_with(&cols, d.offset());
        let filt = self.all_filters(members);
        let mut residual = engine.residual_unweighted(&cols, d.offset(), &ev.beta);
        let (fit_ch, logdet, cv_ch) = if filt.is_empty() {
            let fit_ch: [f64; 6] = std::array::from_fn(|c| {
                residual
                    .iter()
                    .map(|r| (r[c] * self.w[c]).powi(2))
                    .sum::<f64>()
            });
            (fit_ch, [0.0; 6], ev.sse_cv_ch)
        } else {
            let (fit_ch, logdet) = residual_score(self.s, &residual, &filt, &self.noise);
            let mut nuisance = self.design.nuisance.clone();
            nuisance.extend(d.names.iter().flatten().map(|(n, _)| is_start_nuisance(n)));
            let held = engine.held_out_residual(&cols, d.offset(), &ev, &nuisance);
            let (cv_ch, _) = residual_score(self.s, &held, &filt, &self.noise);
            residual = whitened_residual(self.s, &residual, &filt, &self.noise);
            (fit_ch, logdet, cv_ch)
        };
        let kappa_ch: [f64; 6] = std::array::from_fn(|c| {
            let r: Vec<f64> = residual.iter().map(|x| x[c]).collect();
            stats::batch_means_factor(&r)
        });
        let kappa = kappa_ch.iter().sum::<f64>() / 6.0;
        let ld: f64 = logdet.iter().sum();
        (
            Score {
                cv: cv_ch.iter().sum::<f64>() + ld,
                cv_ch,
                fit: fit_ch.iter().sum::<f64>() + ld,
                fit_ch,
                logdet,
                kappa,
                kappa_ch,
                ev,
                widths: d.widths,
                names: d.names,
            },
            residual,
        )
    }

    /// [`Self::score`] without the residual pass where the Gram matrices suffice (no filter of
    /// the target): the autocorrelation factors are then 1 (unknown). For the comparisons
    /// that need only the sums of squares (a set without one member).
    pub fn score_light(&self, engine: &GramEngine<'_>, members: &[Member]) -> Score {
        if !self.all_filters(members).is_empty() {
            return self.score(engine, members);
        }
        let d = self.member_design(members);
        let ev = engine.evaluate_with(&d.cols(), d.offset());
        Score {
            cv: ev.sse_cv(),
            cv_ch: ev.sse_cv_ch,
            fit: ev.sse_full_ch.iter().sum(),
            fit_ch: ev.sse_full_ch,
            logdet: [0.0; 6],
            kappa: 1.0,
            kappa_ch: [1.0; 6],
            ev,
            widths: d.widths,
            names: d.names,
        }
    }

    /// The in-sample score of the model plus `members` (`engine` from [`Self::fit_engine`]),
    /// with the design of member `k` given as `(k, design)`.
    fn fit_score(
        &self,
        engine: &GramEngine<'_>,
        members: &[Member],
        given: Option<(usize, Arc<EffectDesign>)>,
    ) -> f64 {
        let d = self.member_design_given(members, given);
        let cols = d.cols();
        let ev = engine.evaluate_with(&cols, d.offset());
        let filt = self.all_filters(members);
        if filt.is_empty() {
            return ev.sse_full;
        }
        let residual = engine.residual_unweighted(&cols, d.offset(), &ev.beta);
        scan_criterion(self.s, &residual, engine.span(), &filt, &self.noise)
    }

    /// The held-out RMS per channel (N, N m) of a score.
    pub fn held_out_rms(&self, score: &Score) -> [f64; 6] {
        let n = self.s.len().max(1) as f64;
        std::array::from_fn(|c| (score.cv_ch[c] / n).sqrt() / self.w[c])
    }

    /// The engine a scan of member `k` of `members` reads: every `n / 10 000`-th sample of
    /// `engine` for one member without any filter (the fast path), else `None` (`engine`
    /// itself: a filter runs over every sample).
    fn scan_engine<'e>(
        &self,
        engine: &GramEngine<'e>,
        members: &[Member],
        k: usize,
    ) -> Option<GramEngine<'e>> {
        let spec = members[k].effect.scan()?;
        let fast = members.len() == 1
            && self.filters.is_empty()
            && !filters(
                self.s,
                members[k].effect.as_ref(),
                spec.grid.first().copied(),
            );
        fast.then(|| engine.for_scan())
    }

    /// The in-sample criterion of the model plus `trial` with member `k` at `g`: on the scan
    /// engine `fast` when given ([`Self::scan_engine`]), else on `engine`; infinite where a
    /// user's effect has columns of the wrong length.
    fn scan_value(
        &self,
        engine: &GramEngine<'_>,
        fast: Option<&GramEngine<'_>>,
        trial: &mut [Member],
        k: usize,
        g: f64,
    ) -> f64 {
        trial[k].param = Some(g);
        match fast {
            Some(scan) => {
                sampled_effect_design(trial[k].effect.as_ref(), self.s, Some(g), scan.stride())
                    .map_or(f64::INFINITY, |d| {
                        scan.evaluate_sampled(&d.cols, d.offset.as_ref()).sse_full
                            * scan.stride() as f64
                    })
            }
            None => {
                if let Some(score) = self.window_fit_score(engine, trial) {
                    return score;
                }
                match self.length_checked_design(&trial[k]) {
                    Some(d) => self.fit_score(engine, trial, Some((k, d))),
                    None => f64::INFINITY,
                }
            }
        }
    }

    /// [`Self::fit_score`] of a single member on an engine over a window of a long log
    /// ([`Self::fit_engine`]), from the member's columns on the window only
    /// ([`window_effect_design`]: a lag's columns over the whole log would cost five times
    /// more). `None` for several members or an engine over the whole log.
    fn window_fit_score(&self, engine: &GramEngine<'_>, trial: &[Member]) -> Option<f64> {
        let span = engine.span();
        let [m] = trial else { return None };
        // A lag composed with the model's delay (or the reverse) reads the whole log.
        if span == (0..self.s.len()) || self.composes_with_model(m) {
            return None;
        }
        let Some(d) = window_effect_design(m.effect.as_ref(), self.s, m.param, span.clone()) else {
            return Some(f64::INFINITY);
        };
        let ev = engine.evaluate_window(&d.cols, d.offset.as_ref());
        let filt = self.all_filters(trial);
        if filt.is_empty() {
            return Some(ev.sse_full);
        }
        let residual = engine.residual_window_unweighted(&d.cols, d.offset.as_ref(), &ev.beta);
        Some(scan_criterion(self.s, &residual, span, &filt, &self.noise))
    }

    /// Scans member `k`'s parameter with the other members fixed: the in-sample score over
    /// its grid (refined around the best value) and the profile for its interval.
    pub fn scan(&self, engine: &GramEngine<'_>, members: &[Member], k: usize) -> ScanResult {
        let Some(spec) = members[k].effect.scan() else {
            return ScanResult::default();
        };
        let mut trial = members.to_vec();
        let fast = self.scan_engine(engine, members, k);
        let mut profile: Vec<(f64, f64)> = Vec::new();
        let (best, _) = crate::fit::scan_min(&spec.grid, |g| {
            let v = self.scan_value(engine, fast.as_ref(), &mut trial, k, g);
            profile.push((g, v));
            v
        });
        profile.sort_by(|a, b| a.0.total_cmp(&b.0));
        profile.dedup_by(|a, b| a.0 == b.0);
        let (lo, hi) = grid_range(&spec.grid);
        let at_end = best <= lo || best >= hi;
        ScanResult {
            best: Some(best),
            profile,
            at_end,
        }
    }

    /// The 95 % profile interval of member `k`'s scanned parameter from its `scan`, resolved
    /// finer than the interval itself. The minimum is refined by golden sections to
    /// [`MINIMUM_TOLERANCE`] of the value. Then each end is found by bisection on the criterion
    /// (the first value tried beyond it brackets it) to [`INTERVAL_TOLERANCE`] of its distance
    /// from the minimum. A grid's spacing (28 % between a lag's values) or a scan's last bracket
    /// (about 1 %) would otherwise set the interval, however much narrower the evidence is.
    /// `scale` as in [`ScanResult::interval`]. An end of the range where the profile never rises
    /// that far is the interval's end.
    pub fn refined_interval(
        &self,
        engine: &GramEngine<'_>,
        members: &[Member],
        k: usize,
        scan: &ScanResult,
        scale: f64,
    ) -> Option<[f64; 2]> {
        let best = scan.best?;
        if scan.profile.len() < 3 {
            return scan.interval(scale);
        }
        let mut trial = members.to_vec();
        let fast = self.scan_engine(engine, members, k);
        let mut f = |g: f64| self.scan_value(engine, fast.as_ref(), &mut trial, k, g);
        let profile = &scan.profile;
        let at = profile
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.1.total_cmp(&b.1.1))
            .map(|(i, _)| i)?;
        let (mut x_best, mut f_best) = profile[at];
        if !f_best.is_finite() {
            return None;
        }
        // The minimum between the neighbours of the best value tried.
        let (mut a, mut b) = (
            profile[at.saturating_sub(1)].0,
            profile[(at + 1).min(profile.len() - 1)].0,
        );
        let r = 0.5 * (5f64.sqrt() - 1.0);
        let tol = MINIMUM_TOLERANCE * x_best.abs().max(f64::MIN_POSITIVE);
        let (mut x1, mut x2) = (b - r * (b - a), a + r * (b - a));
        let (mut f1, mut f2) = (f(x1), f(x2));
        for _ in 0..60 {
            if b - a <= tol {
                break;
            }
            if f1 < f2 {
                b = x2;
                (x2, f2) = (x1, f1);
                x1 = b - r * (b - a);
                f1 = f(x1);
            } else {
                a = x1;
                (x1, f1) = (x2, f2);
                x2 = a + r * (b - a);
                f2 = f(x2);
            }
        }
        for (x, v) in [(x1, f1), (x2, f2)] {
            if v < f_best {
                (x_best, f_best) = (x, v);
            }
        }
        let limit = f_best + stats::CHI2_1_95 * scale;
        // Each end: bisection between the last value within the limit and the first beyond.
        let mut end = |outside: Option<usize>, range_end: f64| -> f64 {
            let Some(i) = outside else {
                return range_end;
            };
            let (mut inside, mut out) = (x_best, profile[i].0);
            for _ in 0..60 {
                if (out - inside).abs() <= INTERVAL_TOLERANCE * (out - x_best).abs() {
                    break;
                }
                let mid = 0.5 * (inside + out);
                if f(mid) > limit {
                    out = mid;
                } else {
                    inside = mid;
                }
            }
            0.5 * (inside + out)
        };
        let below = profile.iter().rposition(|p| p.0 < x_best && p.1 > limit);
        let above = profile.iter().position(|p| p.0 > x_best && p.1 > limit);
        let lo = end(below, profile[0].0);
        let hi = end(above, profile[profile.len() - 1].0);
        Some([lo.min(best).min(x_best), hi.max(best).max(x_best)])
    }
}

/// The key of member `m`'s design in [`Context`]'s cache: its name and parameter.
fn design_key(m: &Member) -> (String, Option<u64>) {
    (m.name().to_string(), m.param.map(f64::to_bits))
}

/// Relative resolution of each end of a refined profile interval
/// ([`Context::refined_interval`]): 1 % of its distance from the minimum.
pub const INTERVAL_TOLERANCE: f64 = 1e-2;

/// Relative resolution of the minimum of a refined profile interval
/// ([`Context::refined_interval`]): 1e-4 of its value, finer than the narrowest interval of a
/// noise-free log (a few 1e-3 of a lag's time constant).
pub const MINIMUM_TOLERANCE: f64 = 1e-4;

/// The members' fitted columns and known part.
struct MemberDesign {
    designs: Vec<Arc<EffectDesign>>,
    /// The sum of several members' known parts (`None`: at most one).
    summed: Option<ColData>,
    widths: Vec<usize>,
    names: Vec<Vec<(String, String)>>,
}

impl MemberDesign {
    /// Every fitted column, borrowed.
    fn cols(&self) -> Vec<&ColData> {
        self.designs.iter().flat_map(|d| d.cols.iter()).collect()
    }

    /// The members' known part.
    fn offset(&self) -> Option<&ColData> {
        self.summed
            .as_ref()
            .or_else(|| self.designs.iter().find_map(|d| d.offset.as_ref()))
    }
}

/// Subtracts a known part from per-sample values.
fn sub(values: &mut [[f64; 6]], o: &ColData) {
    for (c, d) in o.iter().enumerate() {
        if let Some(v) = d {
            for (x, y) in values.iter_mut().zip(v) {
                x[c] -= y;
            }
        }
    }
}

/// `acc += o`, channel by channel.
fn add_col(acc: &mut ColData, o: ColData) {
    for (a, b) in acc.iter_mut().zip(o) {
        match (a.as_mut(), b) {
            (Some(x), Some(y)) => x.iter_mut().zip(&y).for_each(|(p, q)| *p += q),
            (None, Some(y)) => *a = Some(y),
            _ => {}
        }
    }
}

/// The outcome of a scan ([`Context::scan`]).
#[derive(Debug, Clone, Default)]
pub(crate) struct ScanResult {
    /// The best value (`None`: no scan).
    pub best: Option<f64>,
    /// In-sample score at every value tried, sorted by value.
    pub profile: Vec<(f64, f64)>,
    /// `true` when the best value lies at an end of the range.
    pub at_end: bool,
}

impl ScanResult {
    /// The 95 % profile interval: the values whose in-sample score lies within
    /// `χ²₁(0.95) · scale` of the best (`scale` = the residual variance times its
    /// autocorrelation factor), by linear interpolation between the values tried. An end of the
    /// range where the profile never rises that far is the interval's end.
    pub fn interval(&self, scale: f64) -> Option<[f64; 2]> {
        let best = self.best?;
        let min = self
            .profile
            .iter()
            .map(|p| p.1)
            .fold(f64::INFINITY, f64::min);
        if !min.is_finite() {
            return None;
        }
        let limit = min + stats::CHI2_1_95 * scale;
        let at = self
            .profile
            .iter()
            .position(|p| p.0 >= best)
            .unwrap_or(self.profile.len().saturating_sub(1));
        let cross = |i: usize, j: usize| -> f64 {
            let (a, b) = (self.profile[i], self.profile[j]);
            if (b.1 - a.1).abs() <= 0.0 {
                return b.0;
            }
            a.0 + (limit - a.1) / (b.1 - a.1) * (b.0 - a.0)
        };
        let mut lo = self.profile.first().map_or(best, |p| p.0);
        for i in (0..at).rev() {
            if self.profile[i].1 > limit {
                lo = cross(i + 1, i);
                break;
            }
        }
        let mut hi = self.profile.last().map_or(best, |p| p.0);
        for i in at + 1..self.profile.len() {
            if self.profile[i].1 > limit {
                hi = cross(i - 1, i);
                break;
            }
        }
        Some([lo.min(best), hi.max(best)])
    }
}

/// Why a member is not kept in its set (the first reason that applies).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Refusal {
    /// It raises the held-out error.
    Worse,
    /// Its refit breaks a physical rule.
    Implausible(Violation),
    /// Its scanned parameter's best value lies at an end of its range.
    OutOfRange { value: f64, lo: f64, hi: f64 },
    /// The data cannot tell it apart from `with` (variance inflation `inflation`).
    Confounded { with: String, inflation: f64 },
    /// It fails the significance test.
    NotSignificant { p_value: f64 },
    /// Its held-out gain is below [`MIN_GAIN`].
    Small { gain: f64 },
}

impl Refusal {
    /// The refusal in a phrase.
    pub fn describe(&self) -> String {
        match self {
            Refusal::Worse => "it raises the held-out error".into(),
            Refusal::Implausible(v) => format!("implausible ({}): {}", v.rule, v.note),
            Refusal::OutOfRange { value, lo, hi } => format!(
                "its best value {value:.3} lies at the end of its range {lo:.3}–{hi:.3}: outside the range the data support"
            ),
            Refusal::Confounded { with, inflation } => {
                format!("cannot be told apart from {with} (variance inflation {inflation:.0})")
            }
            Refusal::NotSignificant { p_value } => format!("not significant (p = {p_value:.2e})"),
            Refusal::Small { gain } => format!(
                "too small ({:.1} % of a channel's noise variance)",
                100.0 * gain
            ),
        }
    }
}

/// The verdict on one member of a set.
#[derive(Debug, Clone)]
pub(crate) struct MemberVerdict {
    /// Held-out gain of the member within the set (noise units, whole log).
    pub gain: f64,
    /// Test statistic and its degrees of freedom.
    pub statistic: f64,
    pub dof: usize,
    pub p_value: f64,
    /// The member's coefficients and their standard errors (scaled).
    pub coef: Vec<f64>,
    pub se: Vec<f64>,
    /// Smallest variance inflation of its coefficients within the set (start-of-log
    /// nuisance columns left out): large when none of its directions is told apart.
    pub inflation: f64,
    /// `None`: kept.
    pub refusal: Option<Refusal>,
}

/// A scored set.
#[derive(Debug, Clone)]
pub(crate) struct SetEval {
    pub members: Vec<Member>,
    pub score: Score,
    /// Held-out gain over the model (noise units).
    pub gain: f64,
    /// One verdict per member.
    pub verdicts: Vec<MemberVerdict>,
    /// The scan of each member (default without a scan).
    pub scans: Vec<ScanResult>,
}

impl SetEval {
    /// Every member kept.
    pub fn admissible(&self) -> bool {
        self.gain > 0.0 && self.verdicts.iter().all(|v| v.refusal.is_none())
    }

    /// Names of the members.
    pub fn names(&self) -> Vec<String> {
        self.members.iter().map(|m| m.name().to_string()).collect()
    }
}

/// What the search found for a model.
pub(crate) struct Search {
    /// The model's own score.
    pub base: Score,
    /// Every usable candidate alone, in the order of the candidates.
    pub singles: Vec<SetEval>,
    /// Candidates that could not be evaluated: name and reason.
    pub unavailable: Vec<(String, String)>,
    /// The chosen set (admissible, largest held-out gain), members ordered by their gain alone.
    pub chosen: Option<SetEval>,
    /// Pairs of candidates the data cannot tell apart: names and the inflation.
    pub confounded: Vec<(String, String, f64)>,
    /// Admissible sets that explain the data as well as the chosen one (within the noise of
    /// the comparison) with other members.
    pub alternatives: Vec<SetEval>,
}

/// The physical limits and the starting model's rigid body, which candidates are judged
/// against.
pub(crate) struct Judge<'a> {
    pub limits: &'a Limits,
    /// The model's fitted rigid body (refits are only blamed for what they break).
    pub current: InertialParams,
    /// Mean measured thrust \[N\].
    pub mean_thrust: f64,
    /// Bonferroni divisor.
    pub tests: f64,
    pub alpha: f64,
}

/// The mean measured thrust of a log \[N\].
pub(crate) fn mean_thrust(s: &Signals) -> f64 {
    s.wrench().iter().map(|b| b[2]).sum::<f64>() / s.len().max(1) as f64
}

/// The usable candidates of `opts` for `model`, and the reasons of the others.
pub(crate) fn usable_candidates(
    model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
) -> (Vec<EffectRef>, Vec<(String, String)>) {
    let mut ok = Vec::new();
    let mut not = Vec::new();
    for e in opts.candidates.iter().filter(|c| !model.has(c.name())) {
        // One effect per family: the drag laws (and a wind, which carries a drag) or a lag
        // and a delay would split one physical effect between them.
        if let Some(f) = model
            .effects()
            .iter()
            .find(|f| same_family(e.name(), f.name()))
        {
            not.push((
                e.name().to_string(),
                format!("the model has `{}`, of the same family", f.name()),
            ));
            continue;
        }
        if e.needs_known_mass() && model.known_mass().is_none() {
            not.push((
                e.name().to_string(),
                "needs a known mass (`--mass KG`): a thrust-gain error and a mass error scale the regression alike".into(),
            ));
            continue;
        }
        if let Err(reason) = crate::effects::usable(e.as_ref(), s) {
            not.push((e.name().to_string(), reason));
            continue;
        }
        ok.push(e.clone());
    }
    (ok, not)
}

impl Context<'_> {
    /// Scores and judges the candidate `e` alone, its parameter scanned when it has one
    /// (`base`: the model's own score).
    ///
    /// # Errors
    /// Why its columns cannot enter the regression here, at the scan's start or its best
    /// value (a user's effect may give unusable columns at one of them).
    pub fn judge_single(
        &self,
        engine: &GramEngine<'_>,
        fit_engine: &GramEngine<'_>,
        e: &EffectRef,
        base: &Score,
        judge: &Judge<'_>,
    ) -> Result<SetEval, String> {
        let start = Member {
            effect: e.clone(),
            param: e
                .scan()
                .map(|sp| sp.start.unwrap_or(sp.grid[sp.grid.len() / 2])),
        };
        self.check_design(&start)?;
        let mut member = Member {
            effect: e.clone(),
            param: None,
        };
        let mut scans = ScanResult::default();
        if e.scan().is_some() {
            scans = self.scan(fit_engine, std::slice::from_ref(&member), 0);
            member.param = scans.best;
            self.check_design(&member)?;
        }
        let mut set = self.judge_set(engine, fit_engine, vec![member], base, judge, false);
        set.scans[0] = scans;
        Ok(set)
    }

    /// Scores and judges the set `members` (each scanned member's parameter re-scanned in the
    /// set when `rescan`), with `base` the model's own score.
    pub fn judge_set(
        &self,
        engine: &GramEngine<'_>,
        fit_engine: &GramEngine<'_>,
        mut members: Vec<Member>,
        base: &Score,
        judge: &Judge<'_>,
        rescan: bool,
    ) -> SetEval {
        let mut scans = vec![ScanResult::default(); members.len()];
        for k in 0..members.len() {
            if members[k].effect.scan().is_some() && (rescan || members[k].param.is_none()) {
                let r = self.scan(fit_engine, &members, k);
                members[k].param = r.best;
                scans[k] = r;
            }
        }
        let score = self.score(engine, &members);
        let n = self.s.len() as f64;
        let scales = score.channel_scales(n);
        let nb = self.base_columns();
        let mut verdicts = Vec::with_capacity(members.len());
        let mut offset = nb;
        for (k, m) in members.iter().enumerate() {
            let width = score.widths[k];
            let coef: Vec<f64> = score.ev.beta[offset..offset + width].to_vec();
            let se: Vec<f64> = (offset..offset + width)
                .map(|j| score.std_error(j, n))
                .collect();
            // The effect is told apart when some direction of its columns is: the smallest
            // inflation of its coefficients (one poorly determined coefficient, a vertical drag
            // on a level flight, shows in its interval instead). Start-of-log nuisance
            // columns are not the effect's physics: left out.
            let inflation = (offset..offset + width)
                .zip(&score.names[k])
                .filter(|(_, (name, _))| !is_start_nuisance(name))
                .map(|(j, _)| score.ev.inflation(j))
                .fold(f64::INFINITY, f64::min);
            let inflation = if inflation.is_finite() {
                inflation
            } else {
                1.0
            };
            offset += width;
            let rest: Vec<Member> = members
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != k)
                .map(|(_, m)| m.clone())
                .collect();
            let without = if rest.is_empty() {
                base.clone()
            } else {
                self.score_light(engine, &rest)
            };
            let gain = without.cv - score.cv;
            // The likelihood ratio, each channel in units of its own residual variance and
            // autocorrelation (a channel far from its noise does not drown the others).
            let statistic: f64 = (0..6)
                .map(|c| {
                    let drop = (without.fit_ch[c] + without.logdet[c])
                        - (score.fit_ch[c] + score.logdet[c]);
                    drop.max(0.0) / scales[c]
                })
                .sum();
            let dof = width + usize::from(m.effect.scan().is_some());
            let p_value = stats::chi2_survival(statistic, dof as f64);
            verdicts.push(MemberVerdict {
                gain,
                statistic,
                dof,
                p_value,
                coef,
                se,
                inflation,
                refusal: None,
            });
        }
        // Refusals, in the order of [`Refusal`].
        let theta = self.rigid_theta(&score);
        let theta_se = self.rigid_se(&score);
        let names: Vec<String> = members.iter().map(|m| m.name().to_string()).collect();
        for k in 0..members.len() {
            let v = &verdicts[k];
            let m = &members[k];
            let insignificant =
                v.statistic < stats::chi2_quantile(judge.alpha / judge.tests, v.dof as f64);
            let refusal = if v.gain <= 0.0 {
                Some(Refusal::Worse)
            } else if let Some(viol) =
                self.implausible(m, v, &score.names[k], &theta, &theta_se, judge)
            {
                Some(Refusal::Implausible(viol))
            } else if scans[k].at_end || at_range_end(m) {
                let (lo, hi) = member_range(m);
                Some(Refusal::OutOfRange {
                    value: m.param.unwrap_or(f64::NAN),
                    lo,
                    hi,
                })
            } else if insignificant && v.inflation > MAX_INFLATION {
                // Not significant because the other columns explain what it would: the data
                // cannot tell it apart from them (a clear effect of large inflation is kept:
                // its interval carries the inflation).
                let others: Vec<String> = names
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != k)
                    .map(|(_, n)| format!("`{n}`"))
                    .collect();
                Some(Refusal::Confounded {
                    with: if others.is_empty() {
                        "the rigid body (mass, centre of mass, inertia)".into()
                    } else {
                        others.join(", ")
                    },
                    inflation: v.inflation,
                })
            } else if insignificant {
                Some(Refusal::NotSignificant { p_value: v.p_value })
            } else if v.gain < MIN_GAIN * n {
                Some(Refusal::Small { gain: v.gain / n })
            } else {
                None
            };
            verdicts[k].refusal = refusal;
        }
        SetEval {
            gain: base.cv - score.cv,
            members,
            score,
            verdicts,
            scans,
        }
    }

    /// The rigid body of a score (the first coefficients; the known mass put back).
    pub fn rigid_theta(&self, score: &Score) -> InertialParams {
        let nr = self.rigid_columns();
        let mut theta = [0.0; 10];
        theta[10 - nr..].copy_from_slice(&score.ev.beta[..nr]);
        if let Some(m) = self.model.known_mass() {
            theta[0] = m;
        }
        InertialParams::from_array(theta)
    }

    /// Standard errors of the rigid body of a score ([`Score::std_error`]).
    fn rigid_se(&self, score: &Score) -> [f64; 10] {
        let nr = self.rigid_columns();
        let n = self.s.len() as f64;
        let mut se = [0.0; 10];
        for j in 0..nr {
            se[10 - nr + j] = score.std_error(j, n);
        }
        se
    }

    /// The first physical rule member `m`'s refit breaks: its own, then the rigid body's.
    fn implausible(
        &self,
        m: &Member,
        v: &MemberVerdict,
        names: &[(String, String)],
        theta: &InertialParams,
        theta_se: &[f64; 10],
        judge: &Judge<'_>,
    ) -> Option<Violation> {
        let own: Plausibility = m.effect.plausibility(&v.coef, &v.se, m.param);
        if !own.plausible {
            return Some(Violation {
                rule: if own.rule.is_empty() {
                    "effect".into()
                } else {
                    own.rule.clone()
                },
                note: own.note,
            });
        }
        let coefficients: Vec<(String, String, f64)> = names
            .iter()
            .zip(&v.coef)
            .map(|((n, u), c)| (n.clone(), u.clone(), *c))
            .collect();
        rigid_violation(
            judge.limits,
            &judge.current,
            theta,
            theta_se,
            &coefficients,
            judge.mean_thrust,
        )
    }
}

/// `true` when a member's parameter lies at an end of its scan grid.
fn at_range_end(m: &Member) -> bool {
    let (Some(p), Some(_)) = (m.param, m.effect.scan()) else {
        return false;
    };
    let (lo, hi) = member_range(m);
    p <= lo || p >= hi
}

/// The range of a member's scan grid (NaN without a scan).
fn member_range(m: &Member) -> (f64, f64) {
    m.effect
        .scan()
        .map_or((f64::NAN, f64::NAN), |sp| grid_range(&sp.grid))
}

/// The smallest and largest value of a scan grid.
fn grid_range(grid: &[f64]) -> (f64, f64) {
    (
        grid.iter().copied().fold(f64::INFINITY, f64::min),
        grid.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    )
}

/// Runs the search for the next step from the context's model (module docs); `engine` is
/// the context's [`Context::engine`].
pub(crate) fn search(
    ctx: &Context<'_>,
    engine: &GramEngine<'_>,
    opts: &DiagnoseOptions,
    limits: &Limits,
    current: InertialParams,
) -> Search {
    let (candidates, unavailable) = usable_candidates(&ctx.model, ctx.s, opts);
    let fit_engine = ctx.fit_engine();
    let base = ctx.score(engine, &[]);
    let judge = Judge {
        limits,
        current,
        mean_thrust: mean_thrust(ctx.s),
        tests: candidates.len().max(1) as f64,
        alpha: opts.alpha,
    };
    let mut unavailable = unavailable;
    let mut singles = Vec::new();
    let effects = ctx.model.effects().len();
    let tell = |judging: &str, done: usize, total: usize| {
        opts.progress.report(&super::SearchProgress {
            effects,
            judging,
            done,
            total,
        });
    };
    for (done, e) in candidates.iter().enumerate() {
        tell(e.name(), done, candidates.len());
        match ctx.judge_single(engine, &fit_engine, e, &base, &judge) {
            Ok(set) => singles.push(set),
            Err(reason) => unavailable.push((e.name().to_string(), reason)),
        }
    }
    // The pool of pairs and triples: the best singles by in-sample gain (an effect whose
    // signal lies in one part of the flight, or that needs a partner to be physical, can be
    // worse alone on held-out data).
    let mut order: Vec<usize> = (0..singles.len()).collect();
    let fit_gain = |i: usize| base.fit - singles[i].score.fit;
    order.sort_by(|&a, &b| fit_gain(b).total_cmp(&fit_gain(a)));
    let pool: Vec<usize> = order
        .iter()
        .copied()
        .filter(|&i| fit_gain(i) > 0.0)
        .take(PAIR_POOL)
        .collect();
    let mut sets: Vec<SetEval> = singles.clone();
    let start_of = |i: usize| singles[i].members[0].clone();
    let pairs = pool.len() * pool.len().saturating_sub(1) / 2;
    let mut done = 0;
    for a in 0..pool.len() {
        for b in a + 1..pool.len() {
            tell("pairs", done, pairs);
            done += 1;
            if same_family(start_of(pool[a]).name(), start_of(pool[b]).name()) {
                continue;
            }
            let members = vec![start_of(pool[a]), start_of(pool[b])];
            sets.push(ctx.judge_set(engine, &fit_engine, members, &base, &judge, false));
        }
    }
    let triple_pool: Vec<usize> = pool.iter().copied().take(TRIPLE_POOL).collect();
    let t = triple_pool.len();
    let triples = t * t.saturating_sub(1) * t.saturating_sub(2) / 6;
    let mut done = 0;
    for a in 0..t {
        for b in a + 1..t {
            for c in b + 1..t {
                tell("triples", done, triples);
                done += 1;
                let members = vec![
                    start_of(triple_pool[a]),
                    start_of(triple_pool[b]),
                    start_of(triple_pool[c]),
                ];
                let family = |i: usize, j: usize| same_family(members[i].name(), members[j].name());
                if family(0, 1) || family(0, 2) || family(1, 2) {
                    continue;
                }
                sets.push(ctx.judge_set(engine, &fit_engine, members, &base, &judge, false));
            }
        }
    }
    // Pairs the data cannot tell apart.
    let mut confounded = Vec::new();
    for set in sets.iter().filter(|s| s.members.len() == 2) {
        for v in &set.verdicts {
            if let Some(Refusal::Confounded { inflation, .. }) = &v.refusal {
                confounded.push((set.names()[0].clone(), set.names()[1].clone(), *inflation));
                break;
            }
        }
    }
    // The admissible sets by gain; among those the data cannot tell from the best (a gain
    // within the comparison's noise, [`comparison_margin`]) the one of least prior cost
    // ([`prior_cost`]: a sensor offset before a wind, which is a drag and a force). A set of
    // several members with a scanned one is judged again with its parameters scanned within
    // the set (they may move once the others are in).
    let mut order: Vec<usize> = (0..sets.len()).filter(|&i| sets[i].admissible()).collect();
    order.sort_by(|&a, &b| sets[b].gain.total_cmp(&sets[a].gain));
    if let Some(&top) = order.first() {
        let margin = comparison_margin(sets[top].gain);
        let cost = |i: usize| sets[i].members.iter().map(prior_cost).sum::<f64>();
        order.sort_by(|&a, &b| {
            let near = |i: usize| sets[top].gain - sets[i].gain <= margin;
            near(b)
                .cmp(&near(a))
                .then(if near(a) && near(b) {
                    cost(a).total_cmp(&cost(b))
                } else {
                    std::cmp::Ordering::Equal
                })
                .then(sets[b].gain.total_cmp(&sets[a].gain))
        });
    }
    let mut best = None;
    for i in order {
        let scanned = sets[i].members.iter().any(|m| m.effect.scan().is_some());
        if sets[i].members.len() > 1 && scanned {
            let again = ctx.judge_set(
                engine,
                &fit_engine,
                sets[i].members.clone(),
                &base,
                &judge,
                true,
            );
            if !again.admissible() {
                continue;
            }
            sets[i] = again;
        }
        best = Some(i);
        break;
    }
    let chosen = best.map(|i| {
        let mut set = sets[i].clone();
        // Members in the order of their gain alone.
        let gain_alone = |name: &str| {
            singles
                .iter()
                .find(|s| s.members[0].name() == name)
                .map_or(f64::NEG_INFINITY, |s| s.gain)
        };
        let mut idx: Vec<usize> = (0..set.members.len()).collect();
        idx.sort_by(|&a, &b| {
            gain_alone(set.members[b].name()).total_cmp(&gain_alone(set.members[a].name()))
        });
        set.members = idx.iter().map(|&k| set.members[k].clone()).collect();
        set.verdicts = idx.iter().map(|&k| set.verdicts[k].clone()).collect();
        set.scans = idx.iter().map(|&k| set.scans[k].clone()).collect();
        set
    });
    // Alternatives: admissible sets with other members whose gain is within the comparison's
    // noise of the chosen one (the held-out scores of two sets differ by chance by about
    // twice the square root of their gains).
    let alternatives = match &chosen {
        None => Vec::new(),
        Some(c) => {
            let names: BTreeSet<String> = c.names().into_iter().collect();
            sets.iter()
                .filter(|s| s.admissible())
                .filter(|s| s.names().into_iter().collect::<BTreeSet<_>>() != names)
                .filter(|s| {
                    // Another explanation, not a part of this one or this one and more.
                    let other: BTreeSet<String> = s.names().into_iter().collect();
                    !other.is_subset(&names) && !names.is_subset(&other)
                })
                .filter(|s| (s.gain - c.gain).abs() <= comparison_margin(c.gain.max(s.gain)))
                .cloned()
                .collect()
        }
    };
    Search {
        base,
        singles,
        unavailable,
        chosen,
        confounded,
        alternatives,
    }
}

/// How much two sets' held-out gains (noise units) may differ by chance: twice the square root
/// of the larger gain (the score is a sum of squares in units of the noise; at least 1).
pub(crate) fn chance_margin(gain: f64) -> f64 {
    2.0 * gain.max(1.0).sqrt()
}

/// How much two sets' held-out gains (noise units) may differ for the search to call them
/// alike: [`chance_margin`], at least 1 % of the larger gain (on a long or noise-free log,
/// differences of a percent are not worth another effect).
pub(crate) fn comparison_margin(gain: f64) -> f64 {
    chance_margin(gain).max(0.01 * gain.max(1.0))
}

/// The prior cost of an effect when the data cannot choose between sets. A sensor offset is
/// the commonest cause of what it explains (0.5). A wind is two effects — a drag and a
/// world-fixed force (2). Every other effect is one (1).
fn prior_cost(m: &Member) -> f64 {
    use tagk_dynamics::EffectKind;
    if crate::effects::is_sensor_effect(m.name()) {
        0.5
    } else if EffectKind::from_name(m.name()) == Some(EffectKind::Wind) {
        2.0
    } else {
        1.0
    }
}

/// `true` when the effects named `a` and `b` are both drag laws (a wind includes one): such
/// pairs are not tried together, they would split one physical drag between them. A lag and
/// a delay may go together: a lag filters, a delay shifts, and jittery commands tell them
/// apart (the significance test decides).
fn same_family(a: &str, b: &str) -> bool {
    use tagk_dynamics::EffectKind;
    let drag = |name: &str| EffectKind::from_name(name).is_some_and(EffectKind::includes_drag);
    drag(a) && drag(b)
}
