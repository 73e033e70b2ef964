//! The non-effect sections of a model file: `[motor]` (at the motor shaft), `[plant]`
//! (output-referred mechanics) and `[sensors]`. Each is declared with the same parameter
//! table macro as the effects, so units are checked the same way.

/// `[motor]`: the actuator at the motor shaft (motor-side units — the one exception to the
/// output-referred rule, because these are motor data-sheet numbers).
pub mod motor {
    crate::define_params! {
        /// Input inertia I1 at the motor shaft: rotor + coupling + transmission input (kg·m²).
        inertia: "kg·m²" = 1.0e-5, [1e-12, 1e6], Setting;
        /// Input viscous damping B1 at the motor shaft (N·m·s/rad).
        damping: "N·m·s/rad" = 0.0, [0.0, 1e6], Setting;
        /// Torque limit of the amplifier (N·m at the motor); commands are clipped to ±this.
        max_torque: "N·m" = 2.0, [0.0, 1e6], Setting;
        /// Motor encoder resolution (counts per motor revolution).
        counts_per_rev: "counts/rev" = 2304.0, [1.0, 1e9], Setting;
    }
}

/// `[plant]`: the transmission and the load, referred to the output shaft.
pub mod plant {
    crate::define_params! {
        /// Gear ratio N = motor angle / output angle.
        gear_ratio: "1" = 1.0, [1e-6, 1e6], Setting;
        /// Output inertia I2 (kg·m²): output flange, sensor, load.
        output_inertia: "kg·m²" = 0.0, [0.0, 1e6], Setting;
        /// Output viscous damping B2 (N·m·s/rad), separate from the friction effects.
        output_damping: "N·m·s/rad" = 0.0, [0.0, 1e6], Setting;
        /// 3-mass plant (Eqn 3.3.26): inertia of the intermediate stage, output-referred (kg·m²).
        middle_inertia: "kg·m²" = 0.0, [0.0, 1e6], Setting;
        /// 3-mass plant: proximal stage stiffness Ks between motor and middle (N·m/rad,
        /// output-referred); > 0 selects the 3-mass plant.
        proximal_stiffness: "N·m/rad" = 0.0, [0.0, 1e12], Setting;
        /// 3-mass plant: damping across the proximal stage (N·m·s/rad).
        proximal_damping: "N·m·s/rad" = 0.0, [0.0, 1e9], Setting;
    }
}

/// `[sensors]`: what the card sees besides the motor encoder.
pub mod sensors {
    crate::define_params! {
        /// Output encoder resolution (counts per output rev); 0 = no output encoder (the
        /// thesis never measured output position directly).
        output_counts_per_rev: "counts/rev" = 0.0, [0.0, 1e9], Setting;
        /// Torque sensor resolution (N·m per LSB, output).
        torque_resolution: "N·m" = 0.01, [1e-9, 1e6], Setting;
        /// Torque sensor noise, Gaussian standard deviation (N·m).
        torque_noise: "N·m" = 0.0, [0.0, 1e6], Setting;
        /// Motor velocity sensor resolution (rad/s at the motor; Sensorimotor 1.8e-4).
        velocity_resolution: "rad/s" = 1.8e-4, [1e-12, 1e6], Setting;
        /// Delay of every sensor reading, in 1 kHz samples (whole samples).
        delay: "samples" = 0.0, [0.0, 1000.0], Setting;
    }
}
