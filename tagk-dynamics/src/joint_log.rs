//! Joint-space logs of a fixed-base arm: the CSV the joint-torque diagnosis reads.
//!
//! Columns (any order, one header row, SI units, radians):
//! `t, q1..qN, dq1..dqN, [ddq1..ddqN,] tau1..tauN`.
//! `t` is time \[s\], strictly increasing. `qj` is joint `j`'s position \[rad\], `dqj` its
//! velocity \[rad/s\], `ddqj` its acceleration \[rad/s²\] and `tauj` its measured torque \[N m\].
//! A prismatic joint reads m and N instead. Joints are numbered from 1 in the URDF's
//! depth-first order (that of [`KinematicTree::joint_names`](crate::KinematicTree::joint_names)).
//! The accelerations are all present or all absent; absent, the diagnosis derives them.
//! Other columns are ignored. The reader shares the flight log's CSV parser
//! ([`crate::log`]), so a bad cell is a [`LogError`] naming the file, line and column.

use std::io::{Read, Write};
use std::path::Path;

use crate::log::{LogError, NumericRows, open_log_file};

/// Fewest samples a joint log must have (the same rule as the flight log's
/// [`MIN_ROWS`](crate::log::MIN_ROWS)).
pub const MIN_JOINT_ROWS: usize = crate::log::MIN_ROWS;

/// A joint-space log: time, joint positions, velocities, optional accelerations and torques.
///
/// Each signal holds one row per sample and one entry per joint.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct JointLog {
    /// Time \[s\], strictly increasing.
    pub t: Vec<f64>,
    /// Joint positions \[rad\].
    pub q: Vec<Vec<f64>>,
    /// Joint velocities \[rad/s\].
    pub qd: Vec<Vec<f64>>,
    /// Joint accelerations \[rad/s²\], when logged.
    pub qdd: Option<Vec<Vec<f64>>>,
    /// Measured joint torques \[N m\].
    pub tau: Vec<Vec<f64>>,
    /// The CSV line of each sample (1-based; the header is line 1); empty when built in memory.
    pub lines: Vec<usize>,
}

impl JointLog {
    /// The number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// `true` when the log has no sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The number of joints (0 for an empty log).
    pub fn dof(&self) -> usize {
        self.q.first().map_or(0, Vec::len)
    }

    /// Reads a joint log from a CSV file.
    ///
    /// # Errors
    /// [`LogError::Io`] if the file cannot be opened, otherwise the error of
    /// [`JointLog::read_csv`] wrapped in [`LogError::InFile`] (naming the file).
    pub fn from_csv_path(path: impl AsRef<Path>) -> Result<Self, LogError> {
        let path = path.as_ref();
        let file = open_log_file(path)?;
        Self::read_csv(std::io::BufReader::new(file))
            .map_err(|e| LogError::in_file(path.display().to_string(), e))
    }

    /// Reads a joint log (the [format](self)).
    ///
    /// # Errors
    /// A [`LogError`] naming the line and column of the first problem: a missing column
    /// (`q1` absent, or `dq3` missing while `q3` is there), a cell that is not a finite
    /// number, time that does not increase, or fewer than [`MIN_JOINT_ROWS`] rows.
    pub fn read_csv<R: Read>(reader: R) -> Result<Self, LogError> {
        let mut rows = NumericRows::new(reader)?;
        let header = rows.header.clone();
        let idx = |name: &str| header.iter().position(|h| h == name);
        let missing = |column: String| LogError::MissingColumn { column };
        let t_col = idx("t").ok_or_else(|| missing("t".into()))?;
        let dof = (1..)
            .take_while(|j| idx(&format!("q{j}")).is_some())
            .count();
        if dof == 0 {
            return Err(missing("q1".into()));
        }
        let group = |prefix: &str| -> Result<Vec<usize>, LogError> {
            (1..=dof)
                .map(|j| {
                    idx(&format!("{prefix}{j}")).ok_or_else(|| missing(format!("{prefix}{j}")))
                })
                .collect()
        };
        let q_cols = group("q")?;
        let qd_cols = group("dq")?;
        let tau_cols = group("tau")?;
        let qdd_cols = if (1..=dof).all(|j| idx(&format!("ddq{j}")).is_none()) {
            None
        } else {
            Some(group("ddq")?)
        };
        let used: Vec<usize> = std::iter::once(t_col)
            .chain(q_cols.iter().copied())
            .chain(qd_cols.iter().copied())
            .chain(tau_cols.iter().copied())
            .chain(qdd_cols.iter().flatten().copied())
            .collect();
        // Columns outside the format are read leniently: they are ignored.
        rows.set_lenient((0..header.len()).map(|j| !used.contains(&j)).collect());
        let mut log = JointLog {
            qdd: qdd_cols.as_ref().map(|_| Vec::new()),
            ..JointLog::default()
        };
        let mut values = vec![0.0; header.len()];
        while let Some(line) = rows.next_into(&mut values)? {
            let t = values[t_col];
            if let Some(&previous) = log.t.last()
                && t <= previous
            {
                return Err(LogError::NonIncreasingTime { line, t, previous });
            }
            let pick = |cols: &[usize]| cols.iter().map(|&c| values[c]).collect::<Vec<f64>>();
            log.t.push(t);
            log.q.push(pick(&q_cols));
            log.qd.push(pick(&qd_cols));
            log.tau.push(pick(&tau_cols));
            if let (Some(v), Some(cols)) = (log.qdd.as_mut(), qdd_cols.as_ref()) {
                v.push(pick(cols));
            }
            log.lines.push(line);
        }
        if log.len() < MIN_JOINT_ROWS {
            return Err(LogError::TooShort {
                rows: log.len(),
                needed: MIN_JOINT_ROWS,
            });
        }
        Ok(log)
    }

    /// Checks an in-memory log: equal lengths, one entry per joint, finite values, time
    /// strictly increasing.
    ///
    /// # Errors
    /// [`LogError::LengthMismatch`], [`LogError::NonFinite`] (line = 1-based sample index + 1)
    /// or [`LogError::NonIncreasingTime`].
    pub fn validate(&self) -> Result<(), LogError> {
        let n = self.len();
        let dof = self.dof();
        let mut signals: Vec<(&str, &Vec<Vec<f64>>)> =
            vec![("q", &self.q), ("dq", &self.qd), ("tau", &self.tau)];
        if let Some(qdd) = &self.qdd {
            signals.push(("ddq", qdd));
        }
        for (name, s) in &signals {
            if s.len() != n {
                return Err(LogError::LengthMismatch {
                    column: (*name).to_string(),
                    got: s.len(),
                    expected: n,
                });
            }
            for (i, row) in s.iter().enumerate() {
                if row.len() != dof {
                    return Err(LogError::LengthMismatch {
                        column: format!("{name} (sample {i})"),
                        got: row.len(),
                        expected: dof,
                    });
                }
                if let Some(j) = row.iter().position(|x| !x.is_finite()) {
                    return Err(LogError::NonFinite {
                        line: i + 2,
                        column: format!("{name}{}", j + 1),
                        value: row[j],
                    });
                }
            }
        }
        for (i, w) in self.t.windows(2).enumerate() {
            if !w[0].is_finite() {
                return Err(LogError::NonFinite {
                    line: i + 2,
                    column: "t".into(),
                    value: w[0],
                });
            }
            if w[1] <= w[0] {
                return Err(LogError::NonIncreasingTime {
                    line: i + 3,
                    t: w[1],
                    previous: w[0],
                });
            }
        }
        Ok(())
    }

    /// Writes the log as CSV (the [format](self)), with accelerations when it has them.
    ///
    /// # Errors
    /// The checks of [`JointLog::validate`]; [`LogError::Io`] if writing fails.
    pub fn write_csv<W: Write>(&self, writer: W) -> Result<(), LogError> {
        self.validate()?;
        let io = |e: csv::Error| LogError::Io {
            path: "<csv writer>".into(),
            message: e.to_string(),
        };
        let dof = self.dof();
        let mut w = csv::Writer::from_writer(writer);
        let mut header = vec!["t".to_string()];
        let mut prefixes = vec!["q", "dq"];
        if self.qdd.is_some() {
            prefixes.push("ddq");
        }
        prefixes.push("tau");
        for p in &prefixes {
            header.extend((1..=dof).map(|j| format!("{p}{j}")));
        }
        w.write_record(&header).map_err(io)?;
        for i in 0..self.len() {
            let mut row = vec![format!("{}", self.t[i])];
            let mut push = |v: &[f64]| row.extend(v.iter().map(|x| format!("{x}")));
            push(&self.q[i]);
            push(&self.qd[i]);
            if let Some(qdd) = &self.qdd {
                push(&qdd[i]);
            }
            push(&self.tau[i]);
            w.write_record(&row).map_err(io)?;
        }
        w.flush().map_err(|e| LogError::Io {
            path: "<csv writer>".into(),
            message: e.to_string(),
        })
    }

    /// [`JointLog::write_csv`] to a file (parent directories are created).
    ///
    /// # Errors
    /// As [`JointLog::write_csv`]; I/O errors name the file.
    pub fn write_csv_path(&self, path: impl AsRef<Path>) -> Result<(), LogError> {
        let (file, name) = crate::log::create_file(path.as_ref())?;
        self.write_csv(file).map_err(|e| match e {
            LogError::Io { message, .. } => LogError::Io {
                path: name.clone(),
                message,
            },
            other => other,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn csv(rows: usize, with_qdd: bool) -> String {
        let mut s = String::from(if with_qdd {
            "t,q1,q2,dq1,dq2,ddq1,ddq2,tau1,tau2,note\n"
        } else {
            "t,q1,q2,dq1,dq2,tau1,tau2\n"
        });
        for i in 0..rows {
            let t = i as f64 * 0.01;
            if with_qdd {
                s += &format!("{t},{t},{},1,2,0,0,3,4,x\n", -t);
            } else {
                s += &format!("{t},{t},{},1,2,3,4\n", -t);
            }
        }
        s
    }

    #[test]
    fn reads_both_layouts_and_round_trips() {
        let log = JointLog::read_csv(csv(250, true).as_bytes()).unwrap();
        assert_eq!(log.dof(), 2);
        assert_eq!(log.len(), 250);
        assert_eq!(log.tau[3], vec![3.0, 4.0]);
        assert_eq!(log.lines[0], 2);
        let mut out = Vec::new();
        log.write_csv(&mut out).unwrap();
        let back = JointLog::read_csv(&out[..]).unwrap();
        assert_eq!(back.q, log.q);
        assert_eq!(back.qdd, log.qdd);
        let plain = JointLog::read_csv(csv(250, false).as_bytes()).unwrap();
        assert!(plain.qdd.is_none());
    }

    #[test]
    fn errors_name_line_and_column() {
        let mut text = csv(250, false);
        text = text.replacen("\n0.05,0.05,", "\n0.05,oops,", 1);
        let e = JointLog::read_csv(text.as_bytes()).unwrap_err();
        assert_eq!(e.line(), Some(7));
        assert_eq!(e.column(), Some("q1"));
        let e = JointLog::read_csv("t,q1,q2,dq1,tau1,tau2\n".as_bytes()).unwrap_err();
        assert_eq!(e.column(), Some("dq2"));
        let e = JointLog::read_csv(csv(10, false).as_bytes()).unwrap_err();
        assert!(matches!(e, LogError::TooShort { rows: 10, .. }));
        let partial = csv(250, false).replacen("tau2", "tau2,ddq1", 1);
        let partial = partial
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i == 0 {
                    l.to_string()
                } else {
                    format!("{l},0")
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
        let e = JointLog::read_csv(partial.as_bytes()).unwrap_err();
        assert_eq!(e.column(), Some("ddq2"));
    }
}
