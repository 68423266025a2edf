//! Your PD, as it is: it differentiates its own error, so it keeps the previous one.

/// A PD position loop: acceleration from the position error, limited to ±5 m/s².
#[derive(Default)]
pub struct MyPd {
    previous: Option<f32>,
}

impl MyPd {
    /// One control period: the derivative is the error's change over `dt`.
    pub fn update(&mut self, error: f32, dt: f32) -> f32 {
        let rate = self.previous.map_or(0.0, |p| (error - p) / dt);
        self.previous = Some(error);
        (4.0 * error + 3.6 * rate).clamp(-5.0, 5.0)
    }
}
