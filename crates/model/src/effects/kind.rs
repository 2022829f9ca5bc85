//! The effect kinds: the name of each piece of non-geometric physics, as scenario files,
//! diagnosis reports and model files spell it.
//!
//! The enum is apart from the registry ([`super::registry`]) because every effect file names its
//! own kind while the registry names every effect file: one variant line here, one line there.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

/// Declares [`EffectKind`]: one line per kind, `Variant = "file_name"`, in registry order.
macro_rules! kinds {
    ($($(#[$doc:meta])* $variant:ident = $name:literal,)*) => {
        /// A kind of non-geometric physics (its scenario, report and model-file name in
        /// [`EffectKind::name`]).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum EffectKind {
            $($(#[$doc])* $variant,)*
        }

        impl EffectKind {
            /// Every kind, in registry order (the order of the diagnosis's candidate library).
            pub const ALL: &'static [EffectKind] = &[$(EffectKind::$variant),*];

            /// The name in scenario files, reports and model files (`backlash`, …).
            pub const fn name(self) -> &'static str {
                match self {
                    $(EffectKind::$variant => $name,)*
                }
            }
        }
    };
}

kinds! {
    /// Seed 000 eq. (6): joint errors in the cosines and sines of the first three joints.
    TrigJointErrors = "trig_joint_errors",
    /// Joints deflecting under the gravity torque they carry.
    JointCompliance = "joint_compliance",
    /// Lost motion of a joint: its error flips with the approach direction.
    Backlash = "backlash",
    /// Cyclic gear error, periodic in the joint's own angle.
    TransmissionError = "transmission_error",
    /// Warm-up drift of a joint or of the tip along an axis.
    ThermalDrift = "thermal_drift",
    /// A table axis reading long or short in proportion to travel.
    TableScale = "table_scale",
    /// Two table axes not at right angles.
    TableSquareness = "table_squareness",
    /// The true table-to-world transform differs from the nominal one.
    RegistrationOffset = "registration_offset",
    /// A fitted smooth term, flagged: not physics from the library.
    Discrepancy = "discrepancy",
}

impl EffectKind {
    /// The kind named `name`, if there is one.
    pub fn from_name(name: &str) -> Option<EffectKind> {
        Self::ALL.iter().copied().find(|k| k.name() == name)
    }
}

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for EffectKind {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for EffectKind {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Self::from_name(&name)
            .ok_or_else(|| serde::de::Error::custom(format!("unknown effect kind `{name}`")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_read_back() {
        for k in EffectKind::ALL {
            assert_eq!(EffectKind::from_name(k.name()), Some(*k));
            assert_eq!(k.to_string(), k.name());
            let json = serde_json::to_string(k).unwrap();
            assert_eq!(json, format!("\"{}\"", k.name()));
            assert_eq!(serde_json::from_str::<EffectKind>(&json).unwrap(), *k);
        }
        assert_eq!(EffectKind::from_name("gear_wobble"), None);
    }
}
