//! Checks of one `[devices]` key each, shared by the section's own checks ([`crate::devices::config`])
//! and the drivers' ([`crate::devices::drivers`]): each fails with the key (under `devices.`) and
//! why.

/// A key and why its value is wrong.
pub type KeyError = (String, String);

/// `key` is wrong for `reason`.
pub fn bad(key: &str, reason: impl Into<String>) -> KeyError {
    (key.to_string(), reason.into())
}

/// `v` must be a positive finite number.
pub fn positive(key: &str, v: f64) -> Result<(), KeyError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(key, "must be a positive number"))
    }
}

/// `v` must be zero or a positive finite number.
pub fn non_negative(key: &str, v: f64) -> Result<(), KeyError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(bad(key, "must be zero or positive"))
    }
}
