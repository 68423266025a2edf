//! AUV survey plant: a Girona 500-like vehicle crossing a water current to a target on the sea
//! bed (Leonetti, Kormushev and Sagratella 2012, "Combining local and global direct
//! derivative-free optimization for reinforcement learning", section 5).
//!
//! # The scene
//! World frame x, y horizontal, z depth (positive down, sea surface at z = 0). Below
//! [`AuvConfig::current_depth`] (2 m) a uniform water current of [`AuvConfig::current_speed`]
//! flows along [`AuvConfig::current_direction`] (+x); above it the water is still. The target
//! lies on the sea bed at (0, 0, 4.8) m. The vehicle starts at rest at the surface at
//! [`AuvConfig::start`] = (5, 2, 0) m: outside the current, 5.4 m from the target horizontally
//! and *down*-current of it, so whatever dives towards the target is carried away from it.
//! The sea bed ([`AuvConfig::seabed_depth`] = 4.8 m) and the surface are hard, frictionless
//! limits.
//!
//! # The vehicle (a 3-D point, heading held by the vehicle's own attitude loop)
//! Per world axis i, with water-relative velocity v_r = v − v_c(p):
//!
//! ```text
//! (m + m_a) v̇_i = F_i − d_l v_r,i − d_q |v_r,i| v_r,i          (rigid body + added mass, drag)
//! τ_t Ḟ_i      = sat(F_cmd,i, ±F_max,i) − F_i                  (thrusters: first-order lag)
//! F_cmd,i      = (m + m_a)(v_cmd,i − v_i)/τ_v + d_l v_i + d_q |v_i| v_i
//! ```
//!
//! The last line is the vehicle's own low-level velocity loop: a proportional loop with time
//! constant τ_v plus a feed-forward of the still-water drag at the ground velocity (a DVL
//! measures velocity over ground; the loop does not know the current; it uses the true
//! velocity: the optional measurement noise below applies to what the *policy* sees). In still water
//! and away from saturation it tracks the command with first-order dynamics (time constant τ_v,
//! plus the thrusters' τ_t). In the current, the drag it has to beat exceeds what the
//! thrusters can give: with F_max,x = 30 N and d_q = 148 kg/m the vehicle can hold at most
//! √(30/148) = 0.45 m/s against the water, so a 0.6 m/s current carries it away at
//! ≥ 0.15 m/s whatever the command ("the current is too strong to be fully compensated by the
//! thrusters, and once entered the robot slowly drifts away").
//!
//! # Where the numbers come from
//! The paper ran UWSim/ROS; UWSim's Girona 500 model (`underwater_vehicle_dynamics`,
//! `config/dynamics_g500.yaml` in `uji-ros-pkg/underwater_simulation`) gives the rigid-body mass
//! 98 kg, the translational added mass 49 kg per axis, translational damping linear 0 and
//! quadratic 148 kg/m per axis, and a thruster first-order time constant 0.2 s: these are used
//! as published there (the model is diagonal, as here). The same file's thrusters give
//! about 154 N each (ct·gain² = 6.835e-5 · 1500²), which would let the vehicle stem
//! 1.4 m/s of current, contradicting the paper's statement that 0.6 m/s cannot be compensated.
//! The thrust limits are therefore **our assumption**: 30 N per axis (a thrust-limited
//! low-level loop, e.g. the thruster set-points capped for the mission), chosen so that the
//! vehicle's top speed through the water is 0.45 m/s: above the "simulator" current of
//! 0.5 m/s it still drifts (at ≥ 0.05 m/s), in the "real" 0.6 m/s current at ≥ 0.15 m/s.
//! The velocity-loop time constant τ_v = 1 s, the start point, the control period
//! (0.1 s, 10 Hz, a typical COLA2 rate) and the episode duration (24 s, so that 150 episodes
//! take the paper's hour) are also ours. The integration step is UWSim's 10 ms
//! (semi-implicit Euler, 10 sub-steps per control period).
//!
//! # Disturbances (all off by default, seeded when on)
//! * position and velocity measurement noise (white, Gaussian), seen only through
//!   [`Auv::measurement`]: [`Auv::state`] is the true state;
//! * current turbulence: a first-order Gauss–Markov (Ornstein–Uhlenbeck) perturbation of the
//!   current vector inside the current layer, stationary standard deviation
//!   [`AuvConfig::turbulence_std`] per axis and correlation time
//!   [`AuvConfig::turbulence_time_constant`].
//!
//! The random stream is not rewound by [`Auv::reset`], so with disturbances on, successive
//! episodes differ (as on the sea), while a given seed replays the same sequence of episodes.

use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// Physical and task parameters of the [`Auv`] plant. [`Default`] is the paper's "real"
/// setting (0.6 m/s current); [`AuvConfig::simulator`] the "slightly different" one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AuvConfig {
    /// Rigid-body mass m (kg). UWSim Girona 500: 98.
    pub mass: f64,
    /// Added mass m_a per axis (kg). UWSim Girona 500: 49 on x, y, z.
    pub added_mass: [f64; 3],
    /// Linear drag d_l per axis (N·s/m). UWSim Girona 500: 0 (translation).
    pub linear_drag: [f64; 3],
    /// Quadratic drag d_q per axis (kg/m, force d_q |v| v). UWSim Girona 500: 148.
    pub quadratic_drag: [f64; 3],
    /// Thrust limit F_max per axis (N). Ours: 30 (see the module docs).
    pub max_thrust: [f64; 3],
    /// Thruster time constant τ_t (s). UWSim Girona 500: 0.2.
    pub thruster_time_constant: f64,
    /// Time constant τ_v of the vehicle's own velocity loop (s). Ours: 1.
    pub velocity_time_constant: f64,
    /// Current speed below [`AuvConfig::current_depth`] (m/s). Paper: 0.6 ("real"),
    /// "slightly different" in the simulator phase (0.5 here).
    pub current_speed: f64,
    /// Unit direction of the current (normalised on use). Ours: +x.
    pub current_direction: [f64; 3],
    /// Depth below which the current flows (m). Paper: 2.
    pub current_depth: f64,
    /// Stationary standard deviation of the current turbulence per axis (m/s); 0 = off.
    pub turbulence_std: f64,
    /// Correlation time of the current turbulence (s).
    pub turbulence_time_constant: f64,
    /// Standard deviation of the position measurement noise per axis (m); 0 = off.
    pub position_noise_std: f64,
    /// Standard deviation of the velocity measurement noise per axis (m/s); 0 = off.
    pub velocity_noise_std: f64,
    /// Start position (m), at rest. Ours: (5, 2, 0), at the surface, outside the current.
    pub start: [f64; 3],
    /// Target position (m). Paper: on the sea bed at 4.8 m depth; ours at (0, 0, 4.8).
    pub target: [f64; 3],
    /// The survey radius D (m) of the paper's reward. Paper: 1.
    pub target_radius: f64,
    /// Depth of the sea bed (m), a hard floor. Paper: the target (4.8 m) is on it.
    pub seabed_depth: f64,
    /// Control period (s): one [`Auv::step`]. Ours: 0.1 (10 Hz).
    pub control_period: f64,
    /// Integration sub-steps per control period. Ours: 10 (UWSim's 10 ms step).
    pub substeps: u32,
    /// Episode duration (s). Ours: 24 (150 episodes = 1 hour, as in the paper).
    pub episode_duration: f64,
}

impl AuvConfig {
    /// The paper's "real" environment: 0.6 m/s current, no noise.
    pub const REAL: Self = Self {
        mass: 98.0,
        added_mass: [49.0; 3],
        linear_drag: [0.0; 3],
        quadratic_drag: [148.0; 3],
        max_thrust: [30.0; 3],
        thruster_time_constant: 0.2,
        velocity_time_constant: 1.0,
        current_speed: 0.6,
        current_direction: [1.0, 0.0, 0.0],
        current_depth: 2.0,
        turbulence_std: 0.0,
        turbulence_time_constant: 5.0,
        position_noise_std: 0.0,
        velocity_noise_std: 0.0,
        start: [5.0, 2.0, 0.0],
        target: [0.0, 0.0, 4.8],
        target_radius: 1.0,
        seabed_depth: 4.8,
        control_period: 0.1,
        substeps: 10,
        episode_duration: 24.0,
    };

    /// The "simulator" of the paper's global phase: the same scene with a 0.5 m/s current.
    pub const fn simulator() -> Self {
        Self {
            current_speed: 0.5,
            ..Self::REAL
        }
    }

    /// `Ok` when every parameter is physically meaningful, else the name of the first bad one.
    pub fn validate(&self) -> Result<(), &'static str> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let non_neg = |v: f64| v.is_finite() && v >= 0.0;
        if !pos(self.mass) {
            return Err("mass");
        }
        if !self.added_mass.iter().all(|&v| non_neg(v)) {
            return Err("added_mass");
        }
        if !self.linear_drag.iter().all(|&v| non_neg(v)) {
            return Err("linear_drag");
        }
        if !self.quadratic_drag.iter().all(|&v| non_neg(v)) {
            return Err("quadratic_drag");
        }
        if !self.max_thrust.iter().all(|&v| pos(v)) {
            return Err("max_thrust");
        }
        if !pos(self.thruster_time_constant) {
            return Err("thruster_time_constant");
        }
        if !pos(self.velocity_time_constant) {
            return Err("velocity_time_constant");
        }
        if !non_neg(self.current_speed) {
            return Err("current_speed");
        }
        if !self.current_direction.iter().all(|v| v.is_finite())
            || norm(self.current_direction) == 0.0
        {
            return Err("current_direction");
        }
        if !self.current_depth.is_finite() {
            return Err("current_depth");
        }
        if !non_neg(self.turbulence_std) {
            return Err("turbulence_std");
        }
        if !pos(self.turbulence_time_constant) {
            return Err("turbulence_time_constant");
        }
        if !non_neg(self.position_noise_std) {
            return Err("position_noise_std");
        }
        if !non_neg(self.velocity_noise_std) {
            return Err("velocity_noise_std");
        }
        if !pos(self.seabed_depth) {
            return Err("seabed_depth");
        }
        let in_water = |p: [f64; 3]| {
            p.iter().all(|v| v.is_finite()) && p[2] >= 0.0 && p[2] <= self.seabed_depth
        };
        if !in_water(self.start) {
            return Err("start");
        }
        if !in_water(self.target) {
            return Err("target");
        }
        if !pos(self.target_radius) {
            return Err("target_radius");
        }
        if !pos(self.control_period) {
            return Err("control_period");
        }
        if self.substeps == 0 {
            return Err("substeps");
        }
        if !pos(self.episode_duration) {
            return Err("episode_duration");
        }
        Ok(())
    }

    /// The still-water top speed through the water per axis (m/s), where full thrust meets
    /// drag: d_l v + d_q v² = F_max.
    pub fn top_speed(&self) -> [f64; 3] {
        core::array::from_fn(|i| {
            let (a, b, c) = (
                self.quadratic_drag[i],
                self.linear_drag[i],
                -self.max_thrust[i],
            );
            if a == 0.0 {
                if b == 0.0 { f64::INFINITY } else { -c / b }
            } else {
                (-b + (b * b - 4.0 * a * c).sqrt()) / (2.0 * a)
            }
        })
    }
}

impl Default for AuvConfig {
    fn default() -> Self {
        Self::REAL
    }
}

/// Position, velocity (both world frame, z down) and time of the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AuvState {
    /// Position (m).
    pub position: [f64; 3],
    /// Velocity over ground (m/s).
    pub velocity: [f64; 3],
    /// Time since the start of the episode (s).
    pub time: f64,
}

/// The AUV survey plant (see the [module docs](self)). One episode:
/// [`Auv::reset`], then [`Auv::steps_per_episode`] calls of [`Auv::step`] with the velocity
/// command computed from [`Auv::measurement`].
#[derive(Debug, Clone)]
pub struct Auv {
    config: AuvConfig,
    seed: u64,
    rng: Xoshiro256PlusPlus,
    position: [f64; 3],
    velocity: [f64; 3],
    thrust: [f64; 3],
    turbulence: [f64; 3],
    time: f64,
    steps: usize,
    measured: AuvState,
}

impl Auv {
    /// A plant at the start of an episode. Panics if `config` does not
    /// [validate](AuvConfig::validate) (host harness: a bad config is a bug in the test).
    pub fn new(config: AuvConfig, seed: u64) -> Self {
        if let Err(field) = config.validate() {
            panic!("invalid AuvConfig: {field}");
        }
        let mut auv = Self {
            config,
            seed,
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            position: config.start,
            velocity: [0.0; 3],
            thrust: [0.0; 3],
            turbulence: [0.0; 3],
            time: 0.0,
            steps: 0,
            measured: AuvState {
                position: config.start,
                velocity: [0.0; 3],
                time: 0.0,
            },
        };
        auv.reset();
        auv
    }

    /// Back to the start, at rest, time 0, thrusters idle, turbulence state 0. The random
    /// stream continues (see the module docs); use [`Auv::new`] to replay from the seed.
    pub fn reset(&mut self) {
        self.position = self.config.start;
        self.velocity = [0.0; 3];
        self.thrust = [0.0; 3];
        self.turbulence = [0.0; 3];
        self.time = 0.0;
        self.steps = 0;
        self.measure();
    }

    /// The configuration in use.
    pub fn config(&self) -> &AuvConfig {
        &self.config
    }

    /// The seed given to [`Auv::new`].
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The true state.
    pub fn state(&self) -> AuvState {
        AuvState {
            position: self.position,
            velocity: self.velocity,
            time: self.time,
        }
    }

    /// The state as the vehicle's navigation measures it: the true state plus the configured
    /// noise, drawn once per control step (equal to [`Auv::state`] when the noise is off).
    pub fn measurement(&self) -> AuvState {
        self.measured
    }

    /// The target position (m).
    pub fn target(&self) -> [f64; 3] {
        self.config.target
    }

    /// True distance from the vehicle to the target (m).
    pub fn distance_to_target(&self) -> f64 {
        norm(sub(self.config.target, self.position))
    }

    /// The control period (s): the time one [`Auv::step`] advances.
    pub fn dt(&self) -> f64 {
        self.config.control_period
    }

    /// Control steps in one episode: ⌈episode duration / control period⌉.
    pub fn steps_per_episode(&self) -> usize {
        (self.config.episode_duration / self.config.control_period - 1e-9).ceil() as usize
    }

    /// Control steps taken since the last reset.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The thrust the thrusters currently deliver (N), per axis.
    pub fn thrust(&self) -> [f64; 3] {
        self.thrust
    }

    /// The mean current (without turbulence) at `position` (m/s).
    pub fn current_at(&self, position: [f64; 3]) -> [f64; 3] {
        if position[2] > self.config.current_depth {
            let d = self.config.current_direction;
            let n = norm(d);
            d.map(|c| c / n * self.config.current_speed)
        } else {
            [0.0; 3]
        }
    }

    /// Advances one control period holding the velocity command `velocity_command` (m/s,
    /// world frame, z down) for the vehicle's low-level loop. A non-finite component is
    /// treated as 0 (the low-level loop rejects it), so the state always stays finite.
    pub fn step(&mut self, velocity_command: [f64; 3]) {
        let c = self.config;
        let cmd = velocity_command.map(|v| if v.is_finite() { v } else { 0.0 });
        let h = c.control_period / f64::from(c.substeps);
        for _ in 0..c.substeps {
            // Turbulence: exact discretisation of the Ornstein–Uhlenbeck process.
            if c.turbulence_std > 0.0 {
                let a = (-h / c.turbulence_time_constant).exp();
                let s = c.turbulence_std * (1.0 - a * a).sqrt();
                for i in 0..3 {
                    self.turbulence[i] = a * self.turbulence[i] + s * gaussian(&mut self.rng);
                }
            }
            let mut water = self.current_at(self.position);
            if self.position[2] > c.current_depth {
                for (w, t) in water.iter_mut().zip(self.turbulence) {
                    *w += t;
                }
            }
            for i in 0..3 {
                let m = c.mass + c.added_mass[i];
                let drag = |v: f64| c.linear_drag[i] * v + c.quadratic_drag[i] * v.abs() * v;
                let v = self.velocity[i];
                let demand = m * (cmd[i] - v) / c.velocity_time_constant + drag(v);
                let demand = demand.clamp(-c.max_thrust[i], c.max_thrust[i]);
                // Thruster lag, exact for a step input held over h.
                let k = 1.0 - (-h / c.thruster_time_constant).exp();
                self.thrust[i] += k * (demand - self.thrust[i]);
                // Semi-implicit Euler: velocity first, then position with the new velocity.
                let accel = (self.thrust[i] - drag(v - water[i])) / m;
                self.velocity[i] += h * accel;
                self.position[i] += h * self.velocity[i];
            }
            // Surface and sea bed: hard, inelastic, frictionless.
            if self.position[2] < 0.0 {
                self.position[2] = 0.0;
                self.velocity[2] = self.velocity[2].max(0.0);
            } else if self.position[2] > c.seabed_depth {
                self.position[2] = c.seabed_depth;
                self.velocity[2] = self.velocity[2].min(0.0);
            }
        }
        self.time += c.control_period;
        self.steps += 1;
        self.measure();
    }

    fn measure(&mut self) {
        let (sp, sv) = (
            self.config.position_noise_std,
            self.config.velocity_noise_std,
        );
        let mut m = self.state();
        if sp > 0.0 {
            for p in &mut m.position {
                *p += sp * gaussian(&mut self.rng);
            }
        }
        if sv > 0.0 {
            for v in &mut m.velocity {
                *v += sv * gaussian(&mut self.rng);
            }
        }
        self.measured = m;
    }
}

/// A standard normal deviate (Box–Muller, one of the pair), from 53-bit uniforms.
pub(crate) fn gaussian<R: RngCore>(rng: &mut R) -> f64 {
    let unit = |r: &mut R| (r.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
    let u1 = 1.0 - unit(rng); // (0, 1]: ln is finite
    let u2 = unit(rng);
    (-2.0 * u1.ln()).sqrt() * (core::f64::consts::TAU * u2).cos()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}
