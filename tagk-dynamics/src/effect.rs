//! The vocabulary of physical effects: one name per effect that a rigid-body model of a
//! multirotor leaves out. The simulator shares it (it can put an effect into its plant), and so
//! does the diagnosis (it can fit an effect to a flight log). `tagk simulate --effect NAME` and
//! `tagk diagnose --with NAME` accept the same names.
//!
//! Forces are in the body frame \[N\], torques about the body origin \[N m\], velocities
//! relative to the air in the body frame \[m/s\], rotor speeds `ωᵢ` \[rad/s\].

use core::fmt;

/// The log's battery-voltage column \[V\] (an extra column): the simulator writes it with a
/// `battery-voltage` effect, and the diagnosis's `battery-voltage` candidate reads it.
pub const BATTERY_COLUMN: &str = "vbat";

/// The reference voltage `V_ref` \[V\] of `battery-voltage` (a 1S LiPo mid-flight): the rotor
/// map is nominal at this battery voltage. The simulator's default and the diagnosis share it.
pub const BATTERY_REFERENCE_VOLTAGE: f64 = 3.8;
use core::str::FromStr;

/// A physical effect missing from the rigid-body model.
///
/// The canonical name ([`EffectKind::name`]) is kebab-case; [`EffectKind::from_name`] also
/// accepts the older spellings listed by [`EffectKind::aliases`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum EffectKind {
    /// Linear drag on the air-relative velocity, `f = −D v` (diagonal `D` \[N s/m\]).
    LinearDrag,
    /// Quadratic (bluff-body) drag, `fᵢ = −cᵢ |vᵢ| vᵢ` \[N s²/m²\].
    QuadraticDrag,
    /// Rotor drag (blade flapping and induced drag), proportional to the sum of rotor speeds:
    /// `f = −K (Σ ωᵢ) v` \[kg/rad\].
    RotorDrag,
    /// First-order lag between the commanded and the produced thrust, time constant `τ` \[s\].
    MotorLag,
    /// A pure time delay between the wrench stream and the motion stream \[s\].
    TimeDelay,
    /// Thrust increase near the ground (Cheeseman–Bennett), as a function of height \[m\].
    GroundEffect,
    /// A constant body-frame force \[N\] and torque \[N m\] not produced by the rotors.
    BodyBias,
    /// A constant wind, acting through drag on the air-relative velocity \[m/s\].
    Wind,
    /// A relative error `ε` of the thrust (and reaction-torque) coefficient: the rotors make
    /// `(1 + ε)` times the modelled wrench (dimensionless).
    ThrustGain,
    /// Rotor and motor-bell inertia `J_r` \[kg m²\] about the spin axis: the yaw reaction
    /// torque of the rotors' angular acceleration and the gyroscopic roll/pitch torque of their
    /// spin. Rotor `i` spins at `−sᵢ ωᵢ e_z` (`sᵢ` the reaction-torque sign):
    /// `τ = J_r (Σ sᵢ ω̇ᵢ) e_z + J_r (Σ sᵢ ωᵢ) Ω × e_z`.
    RotorInertia,
    /// Thrust loss of each rotor with its own axial air speed (inflow): rotor `i` makes
    /// `k_f ωᵢ² − k_in ωᵢ v_a,i`, with `v_a,i` the body-`z` air velocity of its hub
    /// \[N s²/(m rad)\]. Its hub forces damp roll and pitch rates.
    RotorInflow,
    /// Per-rotor coefficients: rotor `i` makes `(1 + εᵢ)` times its nominal thrust `k_f ωᵢ²`
    /// and reaction torque `k_m ωᵢ²` (a weak or damaged rotor; dimensionless `εᵢ`).
    RotorImbalance,
    /// Battery-voltage dependence of the rotor map: with the logged battery voltage `V` \[V\],
    /// the rotors make `(1 + β (V − V_ref)/V_ref)` times their nominal thrust `k_f ωᵢ²` and
    /// reaction torque `k_m ωᵢ²` (dimensionless `β`, reference voltage `V_ref` \[V\]).
    BatteryVoltage,
    /// Rotor-speed telemetry delay and filtering: each rotor's reported speed is its speed
    /// `d` \[s\] earlier through a first-order filter of time constant `τ_tel` \[s\]. It lags the
    /// measurement (the log's rotor speeds and the wrench computed from them), not the thrust.
    TelemetryLag,
}

impl EffectKind {
    /// Every effect, in a fixed order (the order of help texts and reports).
    pub const ALL: [EffectKind; 14] = [
        EffectKind::LinearDrag,
        EffectKind::QuadraticDrag,
        EffectKind::RotorDrag,
        EffectKind::MotorLag,
        EffectKind::TimeDelay,
        EffectKind::GroundEffect,
        EffectKind::BodyBias,
        EffectKind::Wind,
        EffectKind::ThrustGain,
        EffectKind::RotorInertia,
        EffectKind::RotorInflow,
        EffectKind::RotorImbalance,
        EffectKind::BatteryVoltage,
        EffectKind::TelemetryLag,
    ];

    /// The canonical kebab-case name, e.g. `"rotor-drag"`.
    pub const fn name(self) -> &'static str {
        match self {
            EffectKind::LinearDrag => "linear-drag",
            EffectKind::QuadraticDrag => "quadratic-drag",
            EffectKind::RotorDrag => "rotor-drag",
            EffectKind::MotorLag => "motor-lag",
            EffectKind::TimeDelay => "time-delay",
            EffectKind::GroundEffect => "ground-effect",
            EffectKind::BodyBias => "body-bias",
            EffectKind::Wind => "wind",
            EffectKind::ThrustGain => "thrust-gain",
            EffectKind::RotorInertia => "rotor-inertia",
            EffectKind::RotorInflow => "rotor-inflow",
            EffectKind::RotorImbalance => "rotor-imbalance",
            EffectKind::BatteryVoltage => "battery-voltage",
            EffectKind::TelemetryLag => "telemetry-lag",
        }
    }

    /// Other accepted spellings of the name (older command-line names).
    pub const fn aliases(self) -> &'static [&'static str] {
        match self {
            EffectKind::BodyBias => &["bias", "wrench-bias", "force-bias"],
            EffectKind::ThrustGain => &["thrust-error", "thrust-coefficient"],
            EffectKind::TimeDelay => &["delay"],
            EffectKind::RotorInertia => &["motor-inertia", "gyroscopic"],
            EffectKind::RotorInflow => &["inflow"],
            EffectKind::RotorImbalance => &["per-rotor-thrust"],
            EffectKind::BatteryVoltage => &["battery"],
            EffectKind::TelemetryLag => &["telemetry-delay", "telemetry-filter"],
            _ => &[],
        }
    }

    /// One line for help texts: what the effect is, in words a flight-dynamics engineer uses.
    pub const fn summary(self) -> &'static str {
        match self {
            EffectKind::LinearDrag => "drag linear in the air-relative velocity, f = -D v",
            EffectKind::QuadraticDrag => "bluff-body drag, f_i = -c_i |v_i| v_i",
            EffectKind::RotorDrag => {
                "rotor drag (blade flapping) at each hub, H_i = -K w_i v_hub, with its moments"
            }
            EffectKind::MotorLag => "first-order lag between commanded and produced thrust",
            EffectKind::TimeDelay => "time delay between the wrench and the motion streams",
            EffectKind::GroundEffect => "thrust increase close to the ground",
            EffectKind::BodyBias => "constant horizontal body-frame force and torque",
            EffectKind::Wind => "constant wind acting through drag on the air-relative velocity",
            EffectKind::ThrustGain => "relative error of the thrust coefficient",
            EffectKind::RotorInertia => {
                "rotor spin inertia J_r: yaw torque of rotor acceleration, gyroscopic roll/pitch"
            }
            EffectKind::RotorInflow => {
                "rotor thrust loss with its axial air speed, dT_i = -k_in w_i v_z,hub, with its moments"
            }
            EffectKind::RotorImbalance => {
                "per-rotor thrust and torque coefficients, (1 + eps_i) k_f w_i^2 (a weak rotor)"
            }
            EffectKind::BatteryVoltage => {
                "rotor map falling with the battery voltage, (1 + beta (V - V_ref)/V_ref) k_f w_i^2"
            }
            EffectKind::TelemetryLag => {
                "rotor-speed telemetry late and filtered: reported w_i lags the rotor by tau_tel"
            }
        }
    }

    /// The physical family the effect belongs to.
    ///
    /// - The three drag laws (`linear-drag`, `quadratic-drag`, `rotor-drag`) are one family,
    ///   `drag`, since a log near hover cannot tell them apart.
    /// - `motor-lag`, `time-delay` and `telemetry-lag` are one family, `timing`. To first order
    ///   in frequency a first-order lag τ is a delay τ. They part only where the lag's amplitude
    ///   roll-off rises above the noise.
    /// - Every other effect is a family of its own, named like it.
    ///
    /// A `wind` fit includes a drag, and so does `rotor-inflow`: [`EffectKind::includes_drag`].
    pub const fn family(self) -> &'static str {
        match self {
            EffectKind::LinearDrag | EffectKind::QuadraticDrag | EffectKind::RotorDrag => "drag",
            EffectKind::MotorLag | EffectKind::TimeDelay | EffectKind::TelemetryLag => "timing",
            other => other.name(),
        }
    }

    /// `true` for effects whose model contains a drag (the drag family; `wind`: drag on
    /// the air-relative velocity; `rotor-inflow`: its force `−k_in Σ|ωᵢ| v_z` is the vertical
    /// row of rotor drag, and of every drag law near hover).
    pub const fn includes_drag(self) -> bool {
        matches!(
            self,
            EffectKind::LinearDrag
                | EffectKind::QuadraticDrag
                | EffectKind::RotorDrag
                | EffectKind::Wind
                | EffectKind::RotorInflow
        )
    }

    /// The effect with this canonical name or alias (ASCII case-insensitive, `_` read as `-`).
    pub fn from_name(name: &str) -> Option<EffectKind> {
        let wanted = name.trim();
        let same = |candidate: &str| {
            candidate.len() == wanted.len()
                && candidate.bytes().zip(wanted.bytes()).all(|(c, w)| {
                    let w = if w == b'_' { b'-' } else { w };
                    c.eq_ignore_ascii_case(&w)
                })
        };
        EffectKind::ALL
            .into_iter()
            .find(|k| same(k.name()) || k.aliases().iter().any(|a| same(a)))
    }
}

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The error of parsing an unknown effect name; its message lists the known names.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown effect `{name}` (known: {known})", known = known_names())]
pub struct UnknownEffect {
    /// The name that was given.
    pub name: String,
}

fn known_names() -> String {
    EffectKind::ALL.map(EffectKind::name).join(", ")
}

impl FromStr for EffectKind {
    type Err = UnknownEffect;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        EffectKind::from_name(s).ok_or_else(|| UnknownEffect {
            name: s.to_string(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_and_alias_parses_back_to_its_effect() {
        for kind in EffectKind::ALL {
            assert_eq!(EffectKind::from_name(kind.name()), Some(kind));
            assert_eq!(kind.to_string().parse::<EffectKind>(), Ok(kind));
            for alias in kind.aliases() {
                assert_eq!(EffectKind::from_name(alias), Some(kind), "{alias}");
            }
        }
        assert_eq!(
            EffectKind::from_name("Rotor_Drag"),
            Some(EffectKind::RotorDrag)
        );
    }

    #[test]
    fn names_and_aliases_are_unique() {
        let mut all: Vec<&str> = EffectKind::ALL
            .iter()
            .flat_map(|k| core::iter::once(k.name()).chain(k.aliases().iter().copied()))
            .collect();
        let count = all.len();
        all.sort_unstable();
        all.dedup();
        assert_eq!(all.len(), count);
    }

    #[test]
    fn an_unknown_name_lists_the_known_ones() {
        let err = "drag".parse::<EffectKind>().unwrap_err();
        let text = err.to_string();
        assert!(text.contains("unknown effect `drag`"), "{text}");
        for kind in EffectKind::ALL {
            assert!(text.contains(kind.name()), "{text}");
        }
    }
}
