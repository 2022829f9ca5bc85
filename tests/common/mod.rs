//! Test helpers shared by several integration tests.

pub mod synthetic8;
pub mod shapes;
