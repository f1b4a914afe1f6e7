//! LQR hover controller for a quadrotor with given inertial parameters.

use nalgebra::{SMatrix, Vector3};
use tagk_dynamics::{InertialParams, QuadrotorModel};

use crate::ControlError;
use crate::dare::{DareOptions, DareSolution, solve_dare, solve_dare_sda};
use crate::quadrotor::{
    DiscreteModel, ErrorState, GainMatrix, OperatingPoint, QuadrotorState, STATE_DIM, StateMatrix,
    discretize, error_state, hover_trim, linearize, to_heading_frame, yaw_of,
};

/// Default control rate of the TAG-K protocol: 50 Hz.
pub const DEFAULT_DT: f64 = 0.02;

/// Quadratic cost weights: `Σ eᵀ Q e + Δuᵀ R Δu` per control step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LqrWeights {
    /// State weight (12×12, symmetric PSD), in the units of the error state
    /// `[m, m/s, rad, rad/s]⁻²`.
    pub q: StateMatrix,
    /// Input weight (4×4, symmetric PD) on rotor-thrust deviations [N⁻²].
    pub r: SMatrix<f64, 4, 4>,
}

impl LqrWeights {
    /// Diagonal weights.
    pub fn from_diagonals(q: [f64; STATE_DIM], r: [f64; 4]) -> Self {
        Self {
            q: StateMatrix::from_diagonal(&q.into()),
            r: SMatrix::<f64, 4, 4>::from_diagonal(&r.into()),
        }
    }

    /// Bryson's-rule weights for the Crazyflie 2.1 (`Q_ii = 1/x_max²`, `R_ii = 1/u_max²`):
    ///
    /// | state | acceptable deviation | weight |
    /// |---|---|---|
    /// | position x, y, z | 0.05 m | 400 |
    /// | velocity x, y, z | 0.25 m/s | 16 |
    /// | roll, pitch error | 0.1 rad | 100 |
    /// | yaw error | 0.2 rad | 25 |
    /// | body rate x, y | 1 rad/s | 1 |
    /// | body rate z | 1 rad/s | 1 |
    /// | each rotor thrust deviation | 0.02 N | 2500 |
    ///
    /// At nominal parameters and 50 Hz the slowest discrete closed-loop pole has `|z| ≈ 0.93`
    /// (time constant ≈ 0.27 s). That is fast enough to track the 0.5 m/s trajectories of the
    /// protocol. The hover trim leaves about 0.058 N of headroom per rotor, roughly three times
    /// the 0.02 N design deviation. With a 50 % payload at 30 % of the arm, `|z| ≈ 0.94`.
    pub fn crazyflie() -> Self {
        Self::from_diagonals(
            [
                400.0, 400.0, 400.0, 16.0, 16.0, 16.0, 100.0, 100.0, 25.0, 1.0, 1.0, 1.0,
            ],
            [2500.0; 4],
        )
    }
}

impl Default for LqrWeights {
    /// [`LqrWeights::crazyflie`].
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// How the controller solves its Riccati equation.
///
/// The default is [`RiccatiSolver::Doubling`] because it is the faster one, even against a
/// warm-started iteration. The plain iteration converges linearly with rate
/// `ρ(A−BK)² ≈ 0.86` for the default Crazyflie design. A warm start `δ` (relative error) away
/// from the solution only saves about `ln(1/δ)/ln(1/ρ²)` of its ≈ 170–190 steps; a 40 % mass
/// change takes 147 instead of 181. Doubling needs 8–9 steps whatever the start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RiccatiSolver {
    /// Riccati difference iteration ([`solve_dare`], the reference): cold start from `Q`
    /// in [`Lqr::new`], warm start from the previous `P` in [`Lqr::redesign`].
    Iteration,
    /// Structure-preserving doubling ([`solve_dare_sda`]) for every solve. It has no use
    /// for a warm start, but converges quadratically.
    #[default]
    Doubling,
}

/// Statistics of the latest Riccati solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveReport {
    /// Solver used.
    pub solver: RiccatiSolver,
    /// Whether it started from the previous solution.
    pub warm_start: bool,
    /// Iterations (Riccati steps or doubling steps).
    pub iterations: usize,
    /// Relative DARE residual of the new `P`.
    pub residual: f64,
}

/// Discrete LQR hover controller of a quadrotor.
///
/// Designed at the hover trim (level, yaw 0) for the given inertial parameters, discretised
/// by zero-order hold at `dt`. The command for an error state `e` (see
/// [`crate::quadrotor`]) is
///
/// ```text
/// u = clamp(u_trim − K e, 0, T_max)   per rotor [N]
/// ```
///
/// **Saturation:** each rotor thrust is clipped independently to
/// `[0, model.max_thrust_per_rotor()]`; no priority between thrust and torques is enforced, so
/// under saturation the applied wrench deviates from the LQR's. [`Lqr::command_unclamped`]
/// gives the raw value.
#[derive(Debug, Clone)]
pub struct Lqr {
    model: QuadrotorModel,
    params: InertialParams,
    weights: LqrWeights,
    options: DareOptions,
    solver: RiccatiSolver,
    trim: OperatingPoint,
    discrete: DiscreteModel,
    p: StateMatrix,
    k: GainMatrix,
    report: SolveReport,
}

struct Design {
    trim: OperatingPoint,
    discrete: DiscreteModel,
}

fn design(
    model: &QuadrotorModel,
    params: &InertialParams,
    dt: f64,
) -> Result<Design, ControlError> {
    let trim = hover_trim(model, params, Vector3::zeros(), 0.0)?;
    let cont = linearize(model, params, &trim)?;
    let discrete = discretize(&cont, dt)?;
    Ok(Design { trim, discrete })
}

impl Lqr {
    /// Designs the controller for `params` (the vehicle's actuator layout comes from
    /// `model`; `model.params` is ignored) with `weights` at sample time `dt` \[s\], using the
    /// default [`RiccatiSolver`] and [`DareOptions`].
    ///
    /// # Errors
    /// Invalid parameters, time step or weights, or a failed Riccati solve.
    pub fn new(
        model: &QuadrotorModel,
        params: &InertialParams,
        weights: LqrWeights,
        dt: f64,
    ) -> Result<Self, ControlError> {
        Self::with_solver(
            model,
            params,
            weights,
            dt,
            RiccatiSolver::default(),
            DareOptions::default(),
        )
    }

    /// [`Lqr::new`] with an explicit solver and stopping rule.
    ///
    /// # Errors
    /// As [`Lqr::new`].
    pub fn with_solver(
        model: &QuadrotorModel,
        params: &InertialParams,
        weights: LqrWeights,
        dt: f64,
        solver: RiccatiSolver,
        options: DareOptions,
    ) -> Result<Self, ControlError> {
        let d = design(model, params, dt)?;
        let sol = match solver {
            RiccatiSolver::Iteration => solve_dare(
                &d.discrete.a,
                &d.discrete.b,
                &weights.q,
                &weights.r,
                &weights.q,
                &options,
            )?,
            RiccatiSolver::Doubling => solve_dare_sda(
                &d.discrete.a,
                &d.discrete.b,
                &weights.q,
                &weights.r,
                &options,
            )?,
        };
        Ok(Self {
            model: *model,
            params: *params,
            weights,
            options,
            solver,
            trim: d.trim,
            discrete: d.discrete,
            report: SolveReport {
                solver,
                warm_start: false,
                iterations: sol.iterations,
                residual: sol.residual,
            },
            p: sol.p,
            k: sol.k,
        })
    }

    /// The nominal Crazyflie 2.1 with [`LqrWeights::crazyflie`] at 50 Hz.
    ///
    /// # Errors
    /// Only if the built-in numbers were invalid (they are tested).
    pub fn crazyflie_default() -> Result<Self, ControlError> {
        let model = QuadrotorModel::crazyflie_2_1();
        Self::new(&model, &model.params, LqrWeights::crazyflie(), DEFAULT_DT)
    }

    /// Re-designs for new inertial parameters (e.g. an accepted estimate): new hover trim,
    /// re-linearisation, ZOH, and a Riccati solve — warm-started from the current `P` with
    /// [`RiccatiSolver::Iteration`], from scratch with [`RiccatiSolver::Doubling`] (the
    /// default, faster; see [`RiccatiSolver`]). On error the controller is left unchanged.
    ///
    /// # Errors
    /// Invalid parameters (non-finite, spatial inertia not positive definite) or a failed
    /// Riccati solve.
    pub fn redesign(&mut self, params: &InertialParams) -> Result<SolveReport, ControlError> {
        let d = design(&self.model, params, self.discrete.dt)?;
        let sol = self.solve(&d.discrete, true)?;
        self.params = *params;
        self.trim = d.trim;
        self.discrete = d.discrete;
        self.p = sol.p;
        self.k = sol.k;
        self.report = SolveReport {
            solver: self.solver,
            warm_start: self.solver == RiccatiSolver::Iteration,
            iterations: sol.iterations,
            residual: sol.residual,
        };
        Ok(self.report)
    }

    fn solve(
        &self,
        d: &DiscreteModel,
        warm: bool,
    ) -> Result<DareSolution<nalgebra::Const<12>, nalgebra::Const<4>>, ControlError> {
        let (q, r) = (&self.weights.q, &self.weights.r);
        Ok(match self.solver {
            RiccatiSolver::Iteration => {
                let p0 = if warm { &self.p } else { q };
                solve_dare(&d.a, &d.b, q, r, p0, &self.options)?
            }
            RiccatiSolver::Doubling => solve_dare_sda(&d.a, &d.b, q, r, &self.options)?,
        })
    }

    /// Selects the Riccati solver for later [`redesign`](Self::redesign) calls.
    pub fn set_solver(&mut self, solver: RiccatiSolver) {
        self.solver = solver;
    }

    /// Rotor thrusts \[N\] for the error state `e` (design frame: hover at yaw 0; see
    /// [`command_for`](Self::command_for) for any heading), clipped per rotor to
    /// `[0, T_max]`. Non-finite entries of `e` count as zero error, so the command is never
    /// NaN.
    pub fn command(&self, e: &ErrorState) -> [f64; 4] {
        let hi = self.model.max_thrust_per_rotor();
        self.command_unclamped(e).map(|t| t.clamp(0.0, hi))
    }

    /// `u_trim − K e` \[N\] without saturation (non-finite entries of `e` count as zero).
    pub fn command_unclamped(&self, e: &ErrorState) -> [f64; 4] {
        let e = e.map(|v| if v.is_finite() { v } else { 0.0 });
        let du = self.k * e;
        core::array::from_fn(|i| self.trim.thrusts[i] - du[i])
    }

    /// Rotor thrusts \[N\] that drive `state` to `reference`: the error
    /// [`error_state`]`(state, reference)`, with its position/velocity blocks rotated into the
    /// reference heading frame ([`to_heading_frame`]), through [`command`](Self::command).
    pub fn command_for(&self, state: &QuadrotorState, reference: &QuadrotorState) -> [f64; 4] {
        let e = error_state(state, reference);
        self.command(&to_heading_frame(&e, yaw_of(&reference.attitude)))
    }

    /// Feedback gain `K` (4×12): `Δu = −K e`.
    pub fn gain(&self) -> &GainMatrix {
        &self.k
    }

    /// Riccati solution `P` (12×12).
    pub fn riccati_solution(&self) -> &StateMatrix {
        &self.p
    }

    /// Hover trim thrusts \[N\] of the current design (unclipped).
    pub fn trim_thrusts(&self) -> [f64; 4] {
        self.trim.thrusts
    }

    /// Hover operating point of the current design (at the origin, yaw 0).
    pub fn operating_point(&self) -> &OperatingPoint {
        &self.trim
    }

    /// Discrete model `(A_d, B_d, dt)` of the current design.
    pub fn discrete_model(&self) -> &DiscreteModel {
        &self.discrete
    }

    /// Closed-loop transition `A_d − B_d K`.
    pub fn closed_loop(&self) -> StateMatrix {
        self.discrete.a - self.discrete.b * self.k
    }

    /// Spectral radius of the closed loop, `max |λ(A_d − B_d K)|` (< 1 means stable).
    pub fn spectral_radius(&self) -> f64 {
        self.closed_loop()
            .complex_eigenvalues()
            .iter()
            .map(|l| l.norm())
            .fold(0.0, f64::max)
    }

    /// Inertial parameters of the current design.
    pub fn params(&self) -> &InertialParams {
        &self.params
    }

    /// Actuator model.
    pub fn model(&self) -> &QuadrotorModel {
        &self.model
    }

    /// Cost weights.
    pub fn weights(&self) -> &LqrWeights {
        &self.weights
    }

    /// Control period \[s\].
    pub fn dt(&self) -> f64 {
        self.discrete.dt
    }

    /// Statistics of the latest Riccati solve.
    pub fn last_solve(&self) -> &SolveReport {
        &self.report
    }
}
