//! Test helpers shared by several integration tests.

pub mod real_shaped;
pub mod shapes;
pub mod synthetic8;
pub mod ur10;
