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
//! - [`procedure`] and [`compare`](mod@compare): the contact procedures, and the rig-time comparison of
//!   procedures and orders `rigcal plan` prints; [`speeds`]: the rig's speeds the estimate and
//!   the optimised order use.
//! - [`error`], [`options`], [`report`]: what stops a session, how to run one, what it did —
//!   each in its own file, so that the steps of a session import them and not each other.
//! - [`setup`]: a session set up as `rigcal session` does (its directory, its `plan.csv`, the
//!   estimate, the options); [`lock`]: one writer per session directory; [`inputs`]: what a
//!   resume must be given again; [`text`]: what `rigcal plan` and `rigcal session` print.

pub mod compare;
mod contact;
mod core;
pub mod error;
pub mod inputs;
pub mod journal;
pub mod lock;
pub mod measurer;
mod motion;
pub mod options;
mod order;
pub mod plan;
pub mod procedure;
mod progress;
mod recovery;
mod registration;
pub mod report;
pub mod run;
mod sensor;
pub mod setup;
pub mod speeds;
pub mod text;

pub use compare::{compare, plan_variant, saving_pct, PlannedVariant, COMPARED};
pub use error::SessionError;
pub use inputs::ResumeCheck;
pub use journal::{Journal, JournalError};
pub use lock::{LockError, SessionLock, LOCK_FILE};
pub use measurer::{
    batch_order, is_division_region, recorded_requests, RecordedRequest, SessionMeasurer,
};
pub use options::{SessionOptions, StopRequest};
pub use plan::{
    estimate, plan, read_plan, registration_candidates, registration_points, write_plan,
    z_window_mm, ContactSettings, Ordering, Plan, PlanError, PlanOptions, PlannedPoint,
    RigTimeEstimate, TimeBreakdown, MAX_PLAN_POINTS,
};
pub use procedure::ContactProcedure;
pub use progress::{Progress, ProgressSink};
pub use report::SessionReport;
pub use run::{run_session, Session};
pub use sensor::SensorSettings;
pub use setup::{OwnedDir, PlanSource, SessionSetup, SetupError, PLAN_FILE};
pub use speeds::{MoveTime, RigSpeeds};
pub use text::comparison_text;
