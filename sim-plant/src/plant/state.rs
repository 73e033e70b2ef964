//! The true state of the plant, for recordings and tests (what no sensor sees exactly).

/// Everything physical at the end of the last substep. Angles in rad, velocities in rad/s,
/// torques in N·m; "output-referred" means divided/multiplied by N as the thesis's tables do.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TrueState {
    /// Simulated time (s).
    pub time: f64,
    /// Motor shaft angle (rad at the motor).
    pub motor_angle: f64,
    /// Motor shaft velocity (rad/s at the motor).
    pub motor_velocity: f64,
    /// Motor shaft acceleration over the last substep (rad/s² at the motor).
    pub motor_acceleration: f64,
    /// Intermediate stage angle, output-referred (3-mass; otherwise = motor_angle / N).
    pub middle_angle: f64,
    /// Output angle (rad).
    pub output_angle: f64,
    /// Output velocity (rad/s).
    pub output_velocity: f64,
    /// Output acceleration over the last substep (rad/s²).
    pub output_acceleration: f64,
    /// Transmission deflection, input side minus output, output-referred (rad).
    pub deflection: f64,
    /// Torque transmitted to the output by the transmission spring (N·m; rigid plant: the
    /// torque the actuator delivers, output-referred).
    pub transmission_torque: f64,
    /// Resisting friction torque at the friction node (N·m).
    pub friction_torque: f64,
    /// Torque the output exerts on its environment (N·m) — what an ideal torque sensor reads.
    pub environment_torque: f64,
    /// Torque command as received (N·m at the motor).
    pub command: f64,
    /// Torque the actuator applied after saturation, delay, deadband, … (N·m at the motor).
    pub applied_torque: f64,
    /// Whether the friction node is in its stick state.
    pub stuck: bool,
    /// Whether the last command was clipped at the motor's torque limit.
    pub saturated: bool,
}
