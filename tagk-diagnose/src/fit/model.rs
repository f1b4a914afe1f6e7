//! The model: the rigid-body regressor plus zero or more effects, and its validation.

use std::sync::Arc;

use crate::effects::{Effect, EffectRef, scan_problem};
use crate::error::DiagnoseError;
use crate::fit::{Fit, fit_model};
use crate::signals::Signals;

/// The model: the rigid-body regressor plus zero or more effects.
///
/// ```
/// use tagk_diagnose::{EffectKind, Model, builtin};
/// let m = Model::rigid_body().with_ref(builtin(EffectKind::LinearDrag)?);
/// assert_eq!(m.effects().len(), 1);
/// assert!(m.validate().is_ok());
/// assert!(Model::rigid_body().with_known_mass(-1.0).validate().is_err());
/// # Ok::<(), tagk_diagnose::DiagnoseError>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct Model {
    effects: Vec<EffectRef>,
    known_mass: Option<f64>,
}

impl Model {
    /// The bare rigid-body model `b = Y θ`.
    pub fn rigid_body() -> Self {
        Self::default()
    }

    /// Adds an effect.
    pub fn with<E: Effect + 'static>(self, effect: E) -> Self {
        self.with_ref(Arc::new(effect))
    }

    /// Fixes the mass to a known value \[kg\] (weighed on a scale) instead of fitting it.
    /// Needed to tell a thrust-gain error from a mass error: both scale the whole
    /// regression, so without a known mass a thrust-gain error is unidentifiable.
    /// The mass must be positive and finite ([`Model::validate`]).
    pub fn with_known_mass(mut self, mass: f64) -> Self {
        self.known_mass = Some(mass);
        self
    }

    /// The known mass, if fixed \[kg\].
    pub fn known_mass(&self) -> Option<f64> {
        self.known_mass
    }

    /// Adds a shared effect.
    pub fn with_ref(mut self, effect: EffectRef) -> Self {
        self.effects.push(effect);
        self
    }

    /// The same model without the effect named `name` (the known mass kept).
    pub fn without(&self, name: &str) -> Model {
        Model {
            effects: self
                .effects
                .iter()
                .filter(|e| e.name() != name)
                .cloned()
                .collect(),
            known_mass: self.known_mass,
        }
    }

    /// The effects, in the order added.
    pub fn effects(&self) -> &[EffectRef] {
        &self.effects
    }

    /// `true` if an effect with this name is in the model.
    pub fn has(&self, name: &str) -> bool {
        self.effects.iter().any(|e| e.name() == name)
    }

    /// A short label, e.g. `rigid body + linear-drag`.
    pub fn label(&self) -> String {
        let mut s = "rigid body".to_string();
        for e in &self.effects {
            s.push_str(" + ");
            s.push_str(e.name());
        }
        s
    }

    /// Checks the model: a known mass is positive and finite, effect names are unique (the
    /// same effect twice would make the regression rank deficient), and every scanned
    /// parameter has a non-empty, finite grid. [`fit_model`] runs this first.
    ///
    /// # Errors
    /// [`DiagnoseError::InvalidModel`] saying what is wrong.
    pub fn validate(&self) -> Result<(), DiagnoseError> {
        if let Some(m) = self.known_mass
            && !(m.is_finite() && m > 0.0)
        {
            return Err(DiagnoseError::InvalidModel(format!(
                "known mass {m} kg is not positive and finite"
            )));
        }
        for (k, e) in self.effects.iter().enumerate() {
            if self.effects[..k].iter().any(|f| f.name() == e.name()) {
                return Err(DiagnoseError::InvalidModel(format!(
                    "effect `{}` added twice",
                    e.name()
                )));
            }
            if let Some(problem) = scan_problem(e.as_ref()) {
                return Err(DiagnoseError::InvalidModel(problem));
            }
        }
        Ok(())
    }

    /// Fits the model to a log by weighted batch least squares (see [`fit_model`]).
    ///
    /// # Errors
    /// See [`fit_model`].
    pub fn fit(&self, signals: &Signals) -> Result<Fit, DiagnoseError> {
        fit_model(self, signals, None)
    }
}
