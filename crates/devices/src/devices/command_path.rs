//! How compensated moves reach an arm controller: joint by joint, or through its own Cartesian
//! command. The rig file's `[devices.arm] command_path`; read by the calibration, the paper's
//! section 7 and the CLI, and applied to a session's arm by
//! [`OpenedRig::on_command_path`](crate::devices::factory::OpenedRig::on_command_path).

use serde::{Deserialize, Serialize};

/// How compensated moves reach the arm controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CommandPath {
    /// Joint commands (`MJ`/`DJ`, 0.1°): rounding alone costs about 0.43 mm mean on the RV-M2.
    #[default]
    Joint,
    /// Cartesian commands (`MP`, 0.1 mm / 0.1°) of the compensated joints' nominal pose.
    Cartesian,
}

impl std::fmt::Display for CommandPath {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            CommandPath::Joint => "joint",
            CommandPath::Cartesian => "cartesian",
        })
    }
}
