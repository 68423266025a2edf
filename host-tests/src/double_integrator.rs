//! A 1-D double integrator ẍ = u + d with an unmodelled constant disturbance d: the
//! simplest plant on which a PD leaves a steady error (d / k_p) that a learned correction
//! can reduce. Simulated in f64 with semi-implicit Euler at the control period.

/// The plant's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DoubleIntegrator {
    /// Position (m).
    pub position: f64,
    /// Velocity (m/s).
    pub velocity: f64,
    /// The constant disturbance acceleration (m/s²), unknown to the controller.
    pub disturbance: f64,
    /// Integration step (s).
    pub dt: f64,
}

impl DoubleIntegrator {
    /// At rest at the origin.
    pub fn new(disturbance: f64, dt: f64) -> Self {
        Self {
            position: 0.0,
            velocity: 0.0,
            disturbance,
            dt,
        }
    }

    /// Applies acceleration command `u` for one step.
    pub fn step(&mut self, u: f64) {
        self.velocity += (u + self.disturbance) * self.dt;
        self.position += self.velocity * self.dt;
    }
}
