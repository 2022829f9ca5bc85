//! Automatic measurement sessions (issue 6): plan the points, run them through the device
//! drivers (on the rig or on emulators of a scenario's world), journal every point so a killed
//! session resumes without losing or repeating one.
//!
//! - [`plan`]: points per region, checked for measurability, ordered to cut travel, with a drift
//!   reference and alternating approach directions; a rig-time estimate.
//! - [`run`]: registration, then the points; rows appended and flushed before the next motion.
//! - [`journal`]: the resume state.
//! - [`measurer`]: planning mode through the rig: the division asks, the session measures.

pub mod journal;
pub mod measurer;
pub mod plan;
pub mod run;

pub use journal::{Journal, JournalError};
pub use measurer::{recorded_requests, RecordedRequest, SessionMeasurer};
pub use plan::{
    estimate, plan, read_plan, registration_candidates, registration_points, write_plan,
    ContactSettings, Ordering, Plan, PlanError, PlanOptions, PlannedPoint, RigSpeeds,
    RigTimeEstimate,
};
pub use run::{run_session, Progress, Session, SessionError, SessionOptions, SessionReport};
