//! The simulated robots of seed 001 (Legnani & Tiboni): each a nominal [`Robot`] the schemes
//! calibrate against, and a "real" robot with the paper's errors that makes the measurements.
//!
//! | module | nominal robot | real robot |
//! |---|---|---|
//! | [`scara2`] | [`Scara2`] (closed form, S = x, y) | [`Scara2Real`]: Tables 3, 4, 6 |
//! | [`stewart`] | [`Stewart`] (closed-form inverse, Newton–Raphson direct, S = x y z ψ θ φ) | [`Stewart::perturbed`]: Table 9 |
//! | [`scara3`] | `rigs/scara3.toml` as a [`HeldChain`](rigcal_core::kinematics::HeldChain) | [`Scara3Real`]: Tables 13–15 |
//!
//! [`Robot`]: rigcal_core::kinematics::Robot

pub mod scara2;
pub mod scara3;
pub mod stewart;

pub use scara2::{Scara2, Scara2Errors, Scara2Random, Scara2Real};
pub use scara3::Scara3Real;
pub use stewart::{Stewart, StewartErrors};
