//! Automatic measurement sessions (issue 6): plan the points, run them through the device
//! drivers (on the rig or on emulators of a scenario's world), journal every point so a killed
//! session resumes without losing or repeating one.
//!
//! - [`plan`](mod@plan): points per region, checked for measurability, ordered to cut travel, with a drift
//!   reference and alternating approach directions; a rig-time estimate.
//! - [`run`]: registration, then the points; rows appended and flushed before the next motion,
//!   the choreography on tokio (arm and table together, waits raced against the drives'
//!   supervision, a fault cancelling the motion in progress). Inside: a session core, the
//!   devices as futures, and one procedure per instrument — table-and-panel contact, or a
//!   point sensor — each with its thresholds from the rig file.
//! - [`journal`]: the resume state.
//! - [`measurer`]: planning mode through the rig: the division asks, the session measures.

mod contact;
mod core;
pub mod journal;
pub mod measurer;
mod motion;
mod order;
pub mod plan;
pub mod procedure;
mod progress;
mod recovery;
mod registration;
pub mod run;
mod sensor;

pub use journal::{Journal, JournalError};
pub use measurer::{
    batch_order, is_division_region, recorded_requests, RecordedRequest, SessionMeasurer,
};
pub use plan::{
    estimate, plan, read_plan, registration_candidates, registration_points, write_plan,
    z_window_mm, ContactSettings, MoveTime, Ordering, Plan, PlanError, PlanOptions, PlannedPoint,
    RigSpeeds, RigTimeEstimate, TimeBreakdown,
};
pub use procedure::{
    compare, plan_variant, saving_pct, ContactProcedure, PlannedVariant, COMPARED,
};
pub use progress::{Progress, ProgressSink};
pub use run::{run_session, Session, SessionError, SessionOptions, SessionReport};
pub use sensor::SensorSettings;
