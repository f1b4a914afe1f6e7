//! How each log of a diagnosis is sampled — its median step, its gaps (where, how long) and
//! its irregular steps — and what the diagnosis did about it (split at the gaps, resampled).
//!
//! The findings are measured on the log as it was read ([`FlightLog::sampling`]), before any
//! resampling, and travel with the [`Report`](crate::Report): the terminal, the JSON and the
//! HTML report show the same lines ([`SamplingFindings::text`]).

use serde::Serialize;
use tagk_dynamics::log::{FlightLog, Sampling};

/// How one log is sampled and what the diagnosis did about it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SamplingFindings {
    /// The log (its file), for a diagnosis of several logs; empty for one.
    pub log: String,
    /// The time stamps' median step, gaps and irregular steps, as read.
    #[serde(flatten)]
    pub sampling: Sampling,
    /// Segments the log is fitted as: one more than the gaps (nothing is differentiated,
    /// lagged or shifted across a gap).
    pub segments: usize,
    /// The uniform step \[s\] the log was resampled onto by linear interpolation within each
    /// segment (`--resample`), if it was.
    pub resampled_step: Option<f64>,
}

impl SamplingFindings {
    /// The findings for `log` named `name`, resampled onto `resampled_step` \[s\] if given.
    pub fn of(name: impl Into<String>, log: &FlightLog, resampled_step: Option<f64>) -> Self {
        let sampling = log.sampling();
        Self {
            log: name.into(),
            segments: sampling.gaps.len() + 1,
            sampling,
            resampled_step,
        }
    }

    /// `true` when the log has neither gaps nor irregular steps (and was not resampled):
    /// nothing to report beyond its rate.
    pub fn is_regular(&self) -> bool {
        self.sampling.is_regular() && self.resampled_step.is_none()
    }

    /// The findings in the report's words: the median step, each gap, the irregular steps,
    /// then what was done (resampled, split). One line each, no trailing newline.
    pub fn text(&self) -> String {
        let mut lines = vec![self.sampling.to_string()];
        if let Some(dt) = self.resampled_step {
            lines.push(format!(
                "resampled: linear interpolation onto a uniform {dt} s grid within each segment"
            ));
        } else if self.sampling.irregular_steps > 0 {
            lines.push(
                "(`--resample S` resamples it onto a uniform grid by linear interpolation)".into(),
            );
        }
        if self.segments > 1 {
            lines.push(format!(
                "split at the gaps into {} segments: nothing is differentiated, lagged or shifted across a gap",
                self.segments
            ));
        }
        lines.join("\n")
    }
}

/// The findings of every log that is not regularly sampled, each under its log's name when
/// there are several logs; empty when every log is regular.
pub fn sampling_text(findings: &[SamplingFindings]) -> String {
    let mut out = String::new();
    for f in findings.iter().filter(|f| !f.is_regular()) {
        if !f.log.is_empty() && findings.len() > 1 {
            out.push_str(&f.log);
            out.push_str(":\n");
        }
        out.push_str(&f.text());
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log_with_times(t: Vec<f64>) -> FlightLog {
        let n = t.len();
        FlightLog {
            t,
            position: vec![[0.0; 3]; n],
            velocity: vec![[0.0; 3]; n],
            attitude: vec![[1.0, 0.0, 0.0, 0.0]; n],
            omega: vec![[0.0; 3]; n],
            wrench: vec![[0.0; 6]; n],
            accel: None,
            omega_dot: None,
            rotor_speeds: None,
            extra: Vec::new(),
        }
    }

    #[test]
    fn a_gap_is_found_where_it_is_and_serialised() {
        // 50 Hz, 1 s missing after t = 2 s.
        let mut t: Vec<f64> = (0..=100).map(|i| f64::from(i) * 0.02).collect();
        t.extend((150..300).map(|i| f64::from(i) * 0.02));
        let f = SamplingFindings::of("a.csv", &log_with_times(t), None);
        assert!(!f.is_regular());
        assert_eq!(f.segments, 2);
        assert_eq!(f.sampling.gaps.len(), 1);
        let g = f.sampling.gaps[0];
        assert_eq!(g.index, 101);
        assert!((g.start - 2.0).abs() < 1e-12 && (g.duration - 1.0).abs() < 1e-9);
        let text = f.text();
        assert!(
            text.contains("gap: 1.000 s long after t = 2.000 s (sample 101)"),
            "{text}"
        );
        assert!(text.contains("split at the gaps into 2 segments"), "{text}");
        let json = serde_json::to_value(&f).unwrap();
        assert_eq!(json["gaps"][0]["index"], 101);
        assert_eq!(json["segments"], 2);
        assert!((json["median_step"].as_f64().unwrap() - 0.02).abs() < 1e-12);
        assert!(json["resampled_step"].is_null());
    }

    #[test]
    fn a_regular_log_reports_nothing_and_a_resampled_one_says_how() {
        let t: Vec<f64> = (0..200).map(|i| f64::from(i) * 0.01).collect();
        let regular = SamplingFindings::of("", &log_with_times(t.clone()), None);
        assert!(regular.is_regular());
        assert_eq!(sampling_text(std::slice::from_ref(&regular)), "");
        let resampled = SamplingFindings::of("", &log_with_times(t), Some(0.005));
        assert!(!resampled.is_regular());
        assert!(
            sampling_text(&[resampled]).contains("uniform 0.005 s grid"),
            "resampling is reported"
        );
    }
}
