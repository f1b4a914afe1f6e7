//! The benchmark's tables: the targets, and the breakdowns by sensing profile, by
//! effect and by strength, from the flights' scores.

use std::fmt::Write as _;

use serde::Serialize;
use tagk_dynamics::EffectKind;
use tagk_sim::SensingProfile;

use super::ground_truth::ACCEL_BIAS;
use super::score::{FlightScore, MASS_TOLERANCE};
use super::{BenchmarkOptions, FlightResult};

/// Edges of the strength bins of [`Summary::bins`] (dimensionless, strength over the noise):
/// `[0, 0.3)`, `[0.3, 1)`, `[1, 3)`, `[3, 10)`, `[10, ∞)`.
pub const STRENGTH_BINS: [f64; 4] = [0.3, 1.0, 3.0, 10.0];

/// One row of the table of targets.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TargetRow {
    /// What is counted.
    pub name: String,
    /// How many met it.
    pub count: usize,
    /// Out of how many.
    pub total: usize,
    /// The target (`—` for an informative row).
    pub target: String,
    /// Whether the target is met (`None`: informative row, or nothing to count).
    pub met: Option<bool>,
}

impl TargetRow {
    /// `count / total` (`None` for an empty total).
    pub fn rate(&self) -> Option<f64> {
        (self.total > 0).then(|| self.count as f64 / self.total as f64)
    }
}

/// The scores of one sensing profile.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProfileRow {
    /// The profile.
    pub sensing: SensingProfile,
    /// Flights drawn with it.
    pub flights: usize,
    /// Of which failed.
    pub failed: usize,
    /// Detectable effects found / detectable effects.
    pub found: (usize, usize),
    /// Clean flights (no true effect) that end with no effect / clean flights.
    pub clean: (usize, usize),
    /// Intervals covering the truth / coefficients with an interval.
    pub covered: (usize, usize),
    /// Mass within 2 % of the truth / flights with a fitted mass.
    pub mass: (usize, usize),
    /// Final models with an implausible coefficient / scored flights.
    pub implausible: (usize, usize),
    /// `adequate` wrong / scored flights.
    pub adequate_wrong: (usize, usize),
}

/// The scores of one true effect (or a diagnosis effect for the coefficient columns).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectRow {
    /// The effect (the vocabulary's name, or [`ACCEL_BIAS`]).
    pub effect: String,
    /// Scored flights where it is a true effect.
    pub truths: usize,
    /// Of which detectable.
    pub detectable: usize,
    /// Detectable and found (by name or stand-in).
    pub found: usize,
    /// Detectable and found in its family.
    pub found_in_family: usize,
    /// Not detectable, yet found.
    pub found_undetectable: usize,
    /// Final models that name it on a flight where it is not a true effect (nor stood in for).
    pub false_positives: usize,
    /// Coefficients of the diagnosis effect of this name compared with a truth.
    pub coefficients: usize,
    /// Their median relative error (`None`: none compared).
    pub median_relative_error: Option<f64>,
    /// Intervals covering the truth / coefficients with an interval.
    pub covered: (usize, usize),
}

/// Found / true effects of one kind in one strength bin.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BinRow {
    /// The effect.
    pub effect: String,
    /// Per bin of [`STRENGTH_BINS`]: `(found, total)`.
    pub bins: Vec<(usize, usize)>,
}

/// Everything aggregated from a run's flights.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// The run's settings.
    pub options: BenchmarkOptions,
    /// Flights run.
    pub flights: usize,
    /// Flights without a score, per stage (`simulator`, `aborted`, `diagnosis`, …).
    pub failures: Vec<(String, usize)>,
    /// The targets, then informative rows.
    pub targets: Vec<TargetRow>,
    /// Per sensing profile.
    pub by_sensing: Vec<ProfileRow>,
    /// Per effect.
    pub by_effect: Vec<EffectRow>,
    /// Found rates by strength.
    pub bins: Vec<BinRow>,
}

/// `x / n` as a percentage with one decimal (`–` for `n = 0`).
fn pct(x: usize, n: usize) -> String {
    if n == 0 {
        "–".into()
    } else {
        format!("{:.1} %", 100.0 * x as f64 / n as f64)
    }
}

/// `found/total (rate)`.
fn frac((x, n): (usize, usize)) -> String {
    if n == 0 {
        "–".into()
    } else {
        format!("{x}/{n} ({})", pct(x, n))
    }
}

/// The median of `v` (`None` when empty).
fn median(mut v: Vec<f64>) -> Option<f64> {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let k = v.len() / 2;
    Some(if !v.len().is_multiple_of(2) {
        v[k]
    } else {
        0.5 * (v[k - 1] + v[k])
    })
}

/// The counters of one group of scores (all, or one profile).
#[derive(Default)]
struct Counts {
    found: (usize, usize),
    found_or_equivalent: (usize, usize),
    in_family: (usize, usize),
    clean: (usize, usize),
    any_false: (usize, usize),
    covered: (usize, usize),
    no_interval: usize,
    mass: (usize, usize),
    mass_identifiable: (usize, usize),
    implausible: (usize, usize),
    diagnosis_implausible: (usize, usize),
    adequate_wrong: (usize, usize),
    adequate_wrong_by_effects: (usize, usize),
}

impl Counts {
    fn of<'a>(scores: impl Iterator<Item = &'a FlightScore>) -> Self {
        let mut c = Self::default();
        for s in scores {
            for e in s.effects.iter().filter(|e| e.detectable) {
                c.found.1 += 1;
                c.found.0 += usize::from(e.found);
                c.found_or_equivalent.1 += 1;
                c.found_or_equivalent.0 += usize::from(e.found_or_equivalent);
                c.in_family.1 += 1;
                c.in_family.0 += usize::from(e.found_in_family);
            }
            if s.is_clean() {
                c.clean.1 += 1;
                c.clean.0 += usize::from(s.final_effects.is_empty());
            }
            c.any_false.1 += 1;
            c.any_false.0 += usize::from(!s.false_effects.is_empty());
            for k in &s.coefficients {
                match k.covered {
                    Some(hit) => {
                        c.covered.1 += 1;
                        c.covered.0 += usize::from(hit);
                    }
                    None => c.no_interval += 1,
                }
            }
            if !s.known_mass {
                c.mass.1 += 1;
                c.mass.0 += usize::from(s.mass_error <= MASS_TOLERANCE);
                c.mass_identifiable.1 += 1;
                c.mass_identifiable.0 += usize::from(s.mass_error_identifiable <= MASS_TOLERANCE);
            }
            c.implausible.1 += 1;
            c.implausible.0 += usize::from(!s.implausible.is_empty());
            c.diagnosis_implausible.1 += 1;
            c.diagnosis_implausible.0 += usize::from(!s.diagnosis_implausible.is_empty());
            c.adequate_wrong.1 += 1;
            c.adequate_wrong.0 += usize::from(!s.adequate_right);
            c.adequate_wrong_by_effects.1 += 1;
            c.adequate_wrong_by_effects.0 += usize::from(!s.adequate_right_by_effects);
        }
        c
    }
}

impl Summary {
    /// Aggregates the results of a run of `options` (flights in any order; failed flights are
    /// counted per stage and left out of every rate).
    pub fn of(options: &BenchmarkOptions, results: &[FlightResult]) -> Self {
        let scores: Vec<&FlightScore> = results.iter().filter_map(|r| r.score.as_ref()).collect();
        let mut failures: Vec<(String, usize)> = Vec::new();
        for f in results.iter().filter_map(|r| r.failure.as_ref()) {
            match failures.iter_mut().find(|(s, _)| *s == f.stage) {
                Some((_, n)) => *n += 1,
                None => failures.push((f.stage.clone(), 1)),
            }
        }
        failures.sort();
        let c = Counts::of(scores.iter().copied());
        // `meets`: whether a rate meets the target (`None` for an informative row).
        let row = |name: &str,
                   (count, total): (usize, usize),
                   target: &str,
                   meets: Option<fn(f64) -> bool>| {
            let mut row = TargetRow {
                name: name.into(),
                count,
                total,
                target: target.into(),
                met: None,
            };
            row.met = meets.zip(row.rate()).map(|(meets, rate)| meets(rate));
            row
        };
        let targets = vec![
            row(
                "detectable effects found (own name or stand-in)",
                c.found,
                "≥ 95 %",
                Some(|r| r >= 0.95),
            ),
            row(
                "flights with no true effect that end with none",
                c.clean,
                "≥ 98 %",
                Some(|r| r >= 0.98),
            ),
            row(
                "coefficient intervals covering the truth",
                c.covered,
                "90–97 %",
                Some(|r| (0.90..=0.97).contains(&r)),
            ),
            row(
                "mass within 2 % of the true mass (mass fitted)",
                c.mass,
                "≥ 95 %",
                Some(|r| r >= 0.95),
            ),
            row(
                "final models with an implausible coefficient",
                c.implausible,
                "0",
                Some(|r| r <= 0.0),
            ),
            row(
                "'adequate' wrong",
                c.adequate_wrong,
                "≤ 2 %",
                Some(|r| r <= 0.02),
            ),
            row(
                "'adequate' wrong, judged by the effects found alone",
                c.adequate_wrong_by_effects,
                "—",
                None,
            ),
            row(
                "detectable effects found, or named as an equivalent of a final-model effect",
                c.found_or_equivalent,
                "—",
                None,
            ),
            row(
                "detectable effects found in their family",
                c.in_family,
                "—",
                None,
            ),
            row(
                "flights with a false effect (any flight)",
                c.any_false,
                "—",
                None,
            ),
            row(
                "mass within 2 % of the identifiable mass (mass fitted)",
                c.mass_identifiable,
                "—",
                None,
            ),
            row(
                "final models the diagnosis itself marks implausible",
                c.diagnosis_implausible,
                "—",
                None,
            ),
            row(
                "compared coefficients without an interval",
                (c.no_interval, c.no_interval + c.covered.1),
                "—",
                None,
            ),
            row("flights scored", (scores.len(), results.len()), "—", None),
        ];
        let by_sensing = SensingProfile::SYNTHETIC
            .iter()
            .map(|p| {
                let of_profile =
                    |r: &&FlightResult| r.spec.as_ref().is_some_and(|s| s.sensing == *p);
                let flights = results.iter().filter(of_profile).count();
                let failed = results
                    .iter()
                    .filter(of_profile)
                    .filter(|r| r.score.is_none())
                    .count();
                let k = Counts::of(scores.iter().copied().filter(|s| s.sensing == *p));
                ProfileRow {
                    sensing: *p,
                    flights,
                    failed,
                    found: k.found,
                    clean: k.clean,
                    covered: k.covered,
                    mass: k.mass,
                    implausible: k.implausible,
                    adequate_wrong: k.adequate_wrong,
                }
            })
            .collect();
        let mut names: Vec<String> = EffectKind::ALL
            .iter()
            .map(|k| k.name().to_string())
            .collect();
        names.push(ACCEL_BIAS.into());
        let by_effect = names
            .iter()
            .map(|name| {
                let mut row = EffectRow {
                    effect: name.clone(),
                    truths: 0,
                    detectable: 0,
                    found: 0,
                    found_in_family: 0,
                    found_undetectable: 0,
                    false_positives: 0,
                    coefficients: 0,
                    median_relative_error: None,
                    covered: (0, 0),
                };
                let mut errors = Vec::new();
                for s in &scores {
                    for e in s.effects.iter().filter(|e| e.name == *name) {
                        row.truths += 1;
                        if e.detectable {
                            row.detectable += 1;
                            row.found += usize::from(e.found);
                            row.found_in_family += usize::from(e.found_in_family);
                        } else {
                            row.found_undetectable += usize::from(e.found);
                        }
                    }
                    row.false_positives += usize::from(s.false_effects.contains(name));
                    for k in s.coefficients.iter().filter(|k| k.effect == *name) {
                        row.coefficients += 1;
                        if let Some(r) = k.relative_error {
                            errors.push(r);
                        }
                        if let Some(hit) = k.covered {
                            row.covered.1 += 1;
                            row.covered.0 += usize::from(hit);
                        }
                    }
                }
                row.median_relative_error = median(errors);
                row
            })
            .collect();
        let bins = names
            .iter()
            .map(|name| {
                let mut bins = vec![(0, 0); STRENGTH_BINS.len() + 1];
                for s in &scores {
                    for e in s.effects.iter().filter(|e| e.name == *name) {
                        let b = STRENGTH_BINS
                            .iter()
                            .filter(|edge| e.strength >= **edge)
                            .count();
                        bins[b].1 += 1;
                        bins[b].0 += usize::from(e.found);
                    }
                }
                BinRow {
                    effect: name.clone(),
                    bins,
                }
            })
            .collect();
        Self {
            options: *options,
            flights: results.len(),
            failures,
            targets,
            by_sensing,
            by_effect,
            bins,
        }
    }

    /// The tables as Markdown: the targets (rate, count, target, met), then per sensing
    /// profile, per effect and by strength.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let o = &self.options;
        let _ = writeln!(
            s,
            "{} flights (seed {}, D = {}{}); {} scored{}.\n",
            self.flights,
            o.seed,
            o.detectable,
            if o.quick { ", quick" } else { "" },
            self.flights - self.failures.iter().map(|(_, n)| n).sum::<usize>(),
            if self.failures.is_empty() {
                String::new()
            } else {
                format!(
                    ", failed: {}",
                    self.failures
                        .iter()
                        .map(|(stage, n)| format!("{stage} {n}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        );
        s.push_str("| target | rate | count | issue's target | met |\n|---|---:|---:|---|---|\n");
        for t in &self.targets {
            let _ = writeln!(
                s,
                "| {} | {} | {}/{} | {} | {} |",
                t.name,
                pct(t.count, t.total),
                t.count,
                t.total,
                t.target,
                match t.met {
                    Some(true) => "yes",
                    Some(false) => "**no**",
                    None => "",
                }
            );
        }
        s.push_str(
            "\nBy sensing profile:\n\n| sensing | flights | failed | detectable found | clean flights with none | intervals covering | mass within 2 % | implausible | 'adequate' wrong |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for p in &self.by_sensing {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                p.sensing,
                p.flights,
                p.failed,
                frac(p.found),
                frac(p.clean),
                frac(p.covered),
                frac(p.mass),
                frac(p.implausible),
                frac(p.adequate_wrong)
            );
        }
        s.push_str(
            "\nBy effect (true effects; the coefficient columns are the diagnosis effect of that name):\n\n| effect | true | detectable | found (of detectable) | in family (of detectable) | found (of undetectable) | false | coefficients | median rel. error | intervals covering |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for e in &self.by_effect {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                e.effect,
                e.truths,
                e.detectable,
                frac((e.found, e.detectable)),
                frac((e.found_in_family, e.detectable)),
                frac((e.found_undetectable, e.truths - e.detectable)),
                e.false_positives,
                e.coefficients,
                e.median_relative_error
                    .map_or_else(|| "–".into(), |r| format!("{:.1} %", 100.0 * r)),
                frac(e.covered)
            );
        }
        s.push_str("\nFound (own name or stand-in) by strength (largest channel RMS over the noise, after the rigid body):\n\n| effect |");
        let mut lo = 0.0;
        for edge in STRENGTH_BINS {
            let _ = write!(s, " [{lo}, {edge}) |");
            lo = edge;
        }
        let _ = writeln!(s, " ≥ {lo} |");
        s.push_str("|---|");
        for _ in 0..=STRENGTH_BINS.len() {
            s.push_str("---:|");
        }
        s.push('\n');
        for b in &self.bins {
            let _ = write!(s, "| {} |", b.effect);
            for (x, n) in &b.bins {
                if *n == 0 {
                    s.push_str(" – |");
                } else {
                    let _ = write!(s, " {x}/{n} |");
                }
            }
            s.push('\n');
        }
        s
    }
}
