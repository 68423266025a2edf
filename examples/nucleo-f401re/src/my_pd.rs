//! Your PD, as it is: it differentiates its own error, so it keeps the previous one. On this
//! board its output is the motor's PWM duty, ±1 being full voltage either way.

/// A PD position loop: duty from the position error (m), limited to ±0.8 so that the
/// learned correction keeps some authority.
#[derive(Default)]
pub struct MyPd {
    previous: Option<f32>,
}

impl MyPd {
    /// One control period: the derivative is the error's change over `dt`.
    pub fn update(&mut self, error: f32, dt: f32) -> f32 {
        let rate = self.previous.map_or(0.0, |p| (error - p) / dt);
        self.previous = Some(error);
        (2.0 * error + 0.5 * rate).clamp(-0.8, 0.8)
    }
}
