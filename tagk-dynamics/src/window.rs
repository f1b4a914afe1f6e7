//! Sliding windows of rigid-body regressor rows: the stacked `A θ ≈ b` an online estimator
//! consumes (docs/CONVENTIONS.md §3: a window of `k` frames stacks `k` 6-row blocks).

use nalgebra::Vector3;

use crate::rigid_body::write_rigid_body_regressor;
use crate::{DynamicsError, Wrench};

/// Values per frame in `A` (6 rows × 10 columns).
pub const A_FRAME_LEN: usize = 60;
/// Values per frame in `b` (6 rows).
pub const B_FRAME_LEN: usize = 6;

/// A ring buffer of the latest `k` frames of rigid-body data, each stored as its 6×10
/// regressor block `Y(a, ω, ω̇)` and the measured actuator wrench `b = [f; τ]`.
///
/// All storage is allocated in [`new`](Self::new); `push`, `build` and `stacked` never
/// allocate. Frames come out oldest first. The same builder serves the simulator (pushing
/// true or noisy kinematics), the diagnosis tool (kinematics from a flight log) and the MCU
/// harness (raw synthetic rows through [`push_rows`](Self::push_rows)).
#[derive(Debug, Clone)]
pub struct WindowBuilder {
    capacity: usize,
    len: usize,
    /// Ring slot the next frame goes to.
    next: usize,
    a_ring: Vec<f64>,
    b_ring: Vec<f64>,
    a_out: Vec<f64>,
    b_out: Vec<f64>,
}

impl WindowBuilder {
    /// A builder holding at most `k` frames (`A` up to `6k × 10`).
    ///
    /// # Errors
    /// [`DynamicsError::EmptyWindow`] if `k == 0`.
    pub fn new(k: usize) -> Result<Self, DynamicsError> {
        if k == 0 {
            return Err(DynamicsError::EmptyWindow);
        }
        Ok(Self {
            capacity: k,
            len: 0,
            next: 0,
            a_ring: vec![0.0; k * A_FRAME_LEN],
            b_ring: vec![0.0; k * B_FRAME_LEN],
            a_out: vec![0.0; k * A_FRAME_LEN],
            b_out: vec![0.0; k * B_FRAME_LEN],
        })
    }

    /// Appends one frame, dropping the oldest when full: the proper acceleration of the body origin
    /// `a` \[m/s²\], angular velocity `ω` \[rad/s\] and acceleration `ω̇` \[rad/s²\] (all body
    /// frame, docs/CONVENTIONS.md §3) and the measured actuator wrench (body frame, about the
    /// origin).
    ///
    /// # Errors
    /// [`DynamicsError::NonFinite`] if any input is NaN/∞; the window is then unchanged.
    pub fn push(
        &mut self,
        accel: &Vector3<f64>,
        omega: &Vector3<f64>,
        omega_dot: &Vector3<f64>,
        wrench: &Wrench,
    ) -> Result<(), DynamicsError> {
        let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
        if !(finite(accel) && finite(omega) && finite(omega_dot)) {
            return Err(DynamicsError::NonFinite {
                what: "window kinematics",
            });
        }
        if !wrench.is_finite() {
            return Err(DynamicsError::NonFinite {
                what: "window wrench",
            });
        }
        let slot = self.next;
        write_rigid_body_regressor(
            accel,
            omega,
            omega_dot,
            &mut self.a_ring[slot * A_FRAME_LEN..(slot + 1) * A_FRAME_LEN],
        )?;
        self.b_ring[slot * B_FRAME_LEN..(slot + 1) * B_FRAME_LEN]
            .copy_from_slice(&wrench.to_array());
        self.advance();
        Ok(())
    }

    /// Appends one frame given directly as 6 regressor rows (`a_rows`: 60 values, row-major)
    /// and 6 measurements `b`, dropping the oldest when full.
    ///
    /// # Errors
    /// [`DynamicsError::DimensionMismatch`] for wrong lengths, [`DynamicsError::NonFinite`]
    /// for NaN/∞; the window is then unchanged.
    pub fn push_rows(&mut self, a_rows: &[f64], b: &[f64]) -> Result<(), DynamicsError> {
        if a_rows.len() != A_FRAME_LEN {
            return Err(DynamicsError::DimensionMismatch {
                what: "frame rows",
                expected: A_FRAME_LEN,
                got: a_rows.len(),
            });
        }
        if b.len() != B_FRAME_LEN {
            return Err(DynamicsError::DimensionMismatch {
                what: "frame measurements",
                expected: B_FRAME_LEN,
                got: b.len(),
            });
        }
        if !a_rows.iter().chain(b).all(|v| v.is_finite()) {
            return Err(DynamicsError::NonFinite {
                what: "window rows",
            });
        }
        let slot = self.next;
        self.a_ring[slot * A_FRAME_LEN..(slot + 1) * A_FRAME_LEN].copy_from_slice(a_rows);
        self.b_ring[slot * B_FRAME_LEN..(slot + 1) * B_FRAME_LEN].copy_from_slice(b);
        self.advance();
        Ok(())
    }

    fn advance(&mut self) {
        self.next = (self.next + 1) % self.capacity;
        self.len = (self.len + 1).min(self.capacity);
    }

    /// Maximum number of frames `k`.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Number of frames held (≤ `k`).
    pub fn len(&self) -> usize {
        self.len
    }

    /// `true` when no frame has been pushed since construction or [`clear`](Self::clear).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// `true` when `k` frames are held.
    pub fn is_full(&self) -> bool {
        self.len == self.capacity
    }

    /// Number of rows of the current window, `6 · len`.
    pub fn rows(&self) -> usize {
        B_FRAME_LEN * self.len
    }

    /// Forgets all frames (no deallocation).
    pub fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
    }

    /// Ring slot of the `i`-th oldest frame held.
    fn slot(&self, i: usize) -> usize {
        (self.next + self.capacity - self.len + i) % self.capacity
    }

    /// Copies the current window, oldest frame first, into `a` (row-major, `6·len × 10`) and
    /// `b` (`6·len`); returns the number of rows written. Entries past them are untouched.
    ///
    /// # Errors
    /// [`DynamicsError::DimensionMismatch`] if `a` or `b` is too short.
    pub fn build(&self, a: &mut [f64], b: &mut [f64]) -> Result<usize, DynamicsError> {
        let rows = self.rows();
        if a.len() < rows * 10 {
            return Err(DynamicsError::DimensionMismatch {
                what: "window A buffer",
                expected: rows * 10,
                got: a.len(),
            });
        }
        if b.len() < rows {
            return Err(DynamicsError::DimensionMismatch {
                what: "window b buffer",
                expected: rows,
                got: b.len(),
            });
        }
        for i in 0..self.len {
            let s = self.slot(i);
            a[i * A_FRAME_LEN..(i + 1) * A_FRAME_LEN]
                .copy_from_slice(&self.a_ring[s * A_FRAME_LEN..(s + 1) * A_FRAME_LEN]);
            b[i * B_FRAME_LEN..(i + 1) * B_FRAME_LEN]
                .copy_from_slice(&self.b_ring[s * B_FRAME_LEN..(s + 1) * B_FRAME_LEN]);
        }
        Ok(rows)
    }

    /// The current window, oldest frame first, as slices of internal storage: `A`
    /// (row-major, `6·len × 10`) and `b` (`6·len`). Ready to hand to
    /// `OnlineEstimator::update`.
    pub fn stacked(&mut self) -> (&[f64], &[f64]) {
        let rows = self.rows();
        let (mut a, mut b) = (
            core::mem::take(&mut self.a_out),
            core::mem::take(&mut self.b_out),
        );
        // Cannot fail: the output buffers hold `k` frames.
        let written = self.build(&mut a, &mut b).unwrap_or(0);
        debug_assert_eq!(written, rows);
        self.a_out = a;
        self.b_out = b;
        (&self.a_out[..rows * 10], &self.b_out[..rows])
    }
}
