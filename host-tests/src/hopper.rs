//! Hopping-leg plant: a ScarlETH-like articulated leg hopping in place over ground whose height
//! changes unseen during flight (Hwangbo et al., "ROCK*: Efficient black-box optimization
//! for policy learning", Humanoids 2014, section IV).
//!
//! # Model
//! Three degrees of freedom, as on the paper's test stand: the main body slides on a vertical
//! rail (its horizontal motion and pitch are locked), the thigh hangs from it at the hip and
//! the shank from the thigh at the knee; both joints are torque controlled. Generalised
//! coordinates q = (y, q_h, q_k):
//! * y — *body height*: height of the hip joint above the world floor z = 0 (m);
//! * q_h — hip angle: thigh from the downward vertical, positive when the knee moves
//!   towards +x (rad);
//! * q_k — knee angle: shank relative to the thigh, **negative when flexed** (rad); the leg
//!   is straight at 0.
//!
//! With the foot at x_f = l₁ sin q_h + l₂ sin(q_h + q_k), y_f = y − l₁ cos q_h − l₂ cos(q_h + q_k),
//! the foot is under the hip when q_h = atan2(−l₂ sin q_k, l₁ + l₂ cos q_k)
//! (q_h = −q_k/2 for equal segments): [`HopperConfig::hip_angle_for_foot_under_hip`].
//!
//! The equations of motion M(q) q̈ + h(q, q̇) = τ + G(q) + J_fᵀ F are built from the segment
//! Jacobians (point masses with rotational inertia about their centres, plus a reflected
//! actuator inertia on each joint), and integrated with classical RK4 at
//! [`HopperConfig::substeps`] sub-steps per control period (default 4 × 0.25 ms under the
//! 1 kHz control step; the joint torques are held over the period, a zero-order hold).
//!
//! # Contact
//! The foot is a point. The normal force is a function of the penetration δ = h_g − y_f and
//! its rate δ̇ = −ẏ_f, chosen by [`HopperConfig::contact`] ([`Contact`]):
//! * **Hunt–Crossley** (the default, [`Contact::RUBBER_FOOT_ON_WOOD`]):
//!   N = max(0, k δⁿ + λ δⁿ δ̇) with n = 3/2 (Hunt & Crossley 1975; Marhefka & Orin, "A
//!   compliant contact model with nonlinear damping for simulation of robotic systems", IEEE
//!   SMC-A 1999, eq. 2). The damping grows with δ, so the force is zero at touchdown whatever
//!   the speed and continuous through the contact. λ = 3/2 α k (their eq. 12), α setting
//!   the coefficient of restitution e ≈ 1 − α v at impact speed v. k = 4/3 E* √R is Hertz's
//!   sphere-on-plane stiffness for an **assumed** rubber ball foot of radius R = 3 cm
//!   (E ≈ 5 MPa, ν = 0.5) on wood (so much stiffer that E* ≈ E/(1 − ν²) ≈ 6.7 MPa):
//!   k = 1.5·10⁶ N/m^1.5, a static sinkage of 0.9 mm under the leg's 41 N. α = 0.2 s/m
//!   is the default of RigidBodyDynamics.jl's `hunt_crossley_hertz` (k there is a generic
//!   5·10⁴); it gives e ≈ 0.6 at the ≈ 2 m/s touchdown from a 0.6 m apex. Neither number
//!   was measured on the paper's wood.
//! * **Linear spring–damper** ([`Contact::LINEAR_SPRING_DAMPER`], the plant's first law,
//!   bit for bit): N = max(0, k δ + c δ̇), 5·10⁴ N/m and 200 N·s/m (assumptions). Its damper
//!   pushes c·v ≈ 400 N the instant the foot touches.
//!
//! The tangential force is
//! a stick–slip model: at touchdown the foot's x is anchored, and F_x = −k_t (x_f − x_anchor)
//! − c_t ẋ_f, limited to |F_x| ≤ μN; when the stick spring would exceed the cone (μ times the
//! spring part of N), the anchor is
//! dragged so that the foot slides. Friction is needed even though the body moves only
//! vertically: without it, the stance leg has nothing to push the knee torque's reaction
//! against and the hip has to hold the whole knee torque (a first frictionless version
//! collapsed on its first landing). With the foot kept under the hip by the joint
//! controller, the foot sticks in normal hopping.
//!
//! # Ground perturbations
//! At each flight apex (body vertical velocity crossing zero out of contact), with
//! probability [`HopperConfig::change_probability`] the ground height is redrawn uniformly from
//! [`HopperConfig::ground_heights`] (default 0, 1.5 and 5.5 cm: the paper's two wooden blocks),
//! provided the foot is clear of the highest one; the draw may repeat the current height. The
//! controller is not told (the paper's perturbations are unperceived); the height is part of
//! [`HopperState`] for logging only. An episode starts on the first height of the set.
//!
//! # Numbers and where they come from
//! The paper gives the structure (vertical body, thigh, shank, hip and knee torque control,
//! 3 DOF), the set apex height 0.6 m and the block heights. Everything else is **our
//! assumption** for a ScarlETH-sized leg (we could not check ScarlETH's published mass
//! budget here): 0.2 m segments; a 3.5 kg main body carrying the actuators (ScarlETH's design
//! goal is light segments with the centre of mass near the hip); a 0.5 kg thigh with its
//! centre 5 cm below the hip; a 0.2 kg shank with its centre 10 cm below the knee; 0.01 kg·m²
//! reflected actuator inertia per joint; 30 N·m torque limits; hip range ±1.2 rad, knee range
//! [−2.5, −0.1] rad with stiff stops beyond; the ground contact above (the Hertz stiffness
//! and α are sourced, the foot's size and rubber are assumed), tangential 5·10⁴ N/m and
//! 200 N·s/m, μ = 0.8. A first choice of a 6 kg body
//! could reach the 0.6 m apex only with the knee torque saturated for a fifth of the time, so
//! the body was lightened to 3.5 kg (4.2 kg in all). The values are in
//! [`HopperConfig::SCARLETH`]; the nominal controller that hops at 0.6 m on them is
//! [`NominalHopping::TUNED`].
//!
//! # Series elasticity (optional)
//! ScarlETH is the *Series Compliant Articulated Robotic Leg*: hip and knee are driven through
//! highly compliant series elastic actuators, "high spring compliance with low damping in
//! combination with a cascaded, motor velocity based, control structure" for joint torque
//! control (Hutter et al., *ScarlETH: design and control of a planar running robot*, IROS 2011;
//! *High compliant series elastic actuation for the robotic leg ScarlETH*, CLAWAR 2011 — we
//! could read only their abstracts, so every number below is **our assumption**). With
//! [`HopperConfig::series_elasticity`] = `Some(`[`SeaConfig`]`)` each joint j gets a motor
//! state (angle θ_j, rate θ̇_j, reflected to the joint side) and:
//!
//! ```text
//! τ_s  = k (θ − q) + b (θ̇ − q̇)                         spring torque, the joint's torque
//! B θ̈ = τ_m − τ_s                                      motor side (reflected inertia B)
//! τ̂    = k (θ − q)                                      measured by the deflection sensor
//! ω_ref = q̇ + 2π f_τ (τ_cmd − τ̂) / k                   outer torque loop → motor velocity
//! τ_m  = sat(τ̂ + B · 2π f_v (ω_ref − θ̇), ±τ_m,max)     inner motor-velocity loop
//! ```
//!
//! While the motor is not saturated and the inner loop is fast (f_v ≫ f_τ), the deflection
//! obeys φ̇ ≈ 2π f_τ (τ_cmd / k − φ): the spring torque follows the command through a
//! first-order lag of bandwidth f_τ, and faster than that (an impact) the joint feels the
//! passive spring. The low-level loop is evaluated inside the ODE (continuous time: an
//! idealised drive much faster than the 1 kHz command). The command τ_cmd is still the
//! policy's torque held over the control period and saturated at
//! [`HopperConfig::torque_limit`]; [`HopperStats::motor_limit_steps`] counts the steps in which
//! a motor hit its limit, and [`HopperStats::absolute_work`] integrates |τ_s q̇|.
//!
//! [`HopperConfig::SCARLETH_SEA`] = the rigid leg with [`SeaConfig::SCARLETH`]: k = 100
//! N·m/rad (30 N·m deflect the spring by 0.3 rad: "high compliance"), b = 0.1 N·m·s/rad
//! ("low damping"), B = 0.01 kg·m² (the rigid leg's reflected actuator inertia, moved behind
//! the spring; 0.001 kg·m² of output-side inertia stays on each joint), f_τ = 20 Hz, f_v =
//! 100 Hz, τ_m,max = 30 N·m; 8 RK4 sub-steps (0.125 ms): with the nominal gait the apexes
//! agree with 16 and 32 sub-steps to 1 mm. Without series elasticity the motor state is
//! carried but never moves, and every result is bit-identical to the plant without it.

use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// The paper's ground heights: floor, 1.5 cm block, 5.5 cm block (m).
pub const BLOCK_HEIGHTS: &[f64] = &[0.0, 0.015, 0.055];

/// Physical and task parameters of the [`Hopper`]. [`Default`] is [`HopperConfig::SCARLETH`]
/// (random blocks); [`HopperConfig::flat`] the same leg on flat ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HopperConfig {
    /// Gravity (m/s²).
    pub gravity: f64,
    /// Main body mass, sliding on the vertical rail (kg).
    pub body_mass: f64,
    /// Thigh mass (kg).
    pub thigh_mass: f64,
    /// Shank mass, foot included (kg).
    pub shank_mass: f64,
    /// Thigh length l₁, hip to knee (m).
    pub thigh_length: f64,
    /// Shank length l₂, knee to foot (m).
    pub shank_length: f64,
    /// Distance from the hip to the thigh's centre of mass (m).
    pub thigh_com: f64,
    /// Distance from the knee to the shank's centre of mass (m).
    pub shank_com: f64,
    /// Thigh inertia about its centre of mass (kg·m²).
    pub thigh_inertia: f64,
    /// Shank inertia about its centre of mass (kg·m²).
    pub shank_inertia: f64,
    /// Reflected actuator inertia on [hip, knee] (kg·m²).
    pub armature: [f64; 2],
    /// Torque limit on [hip, knee] (N·m): commands beyond it are saturated (and counted).
    pub torque_limit: [f64; 2],
    /// Hip angle range [min, max] (rad).
    pub hip_range: [f64; 2],
    /// Knee angle range [min, max] (rad), negative = flexed.
    pub knee_range: [f64; 2],
    /// Stiffness of the joint-limit stops (N·m/rad).
    pub limit_stiffness: f64,
    /// Damping of the joint-limit stops (N·m·s/rad), acting only inside a stop.
    pub limit_damping: f64,
    /// The normal contact law of the foot on the ground ([`Contact`]).
    pub contact: Contact,
    /// Tangential (stick) stiffness of the foot contact (N/m).
    pub tangential_stiffness: f64,
    /// Tangential damping of the foot contact (N·s/m).
    pub tangential_damping: f64,
    /// Coulomb friction coefficient μ: the tangential force never exceeds μ times the normal.
    pub friction: f64,
    /// The ground heights drawn at each apex (m); the episode starts on the first.
    pub ground_heights: &'static [f64],
    /// Probability of a redraw at each apex, in [0, 1].
    pub change_probability: f64,
    /// Body height at the start of an episode, at rest (m).
    pub initial_height: f64,
    /// Knee angle at the start (rad); the hip starts with the foot under it.
    pub initial_knee: f64,
    /// Body height above the ground below which the leg counts as collapsed (m).
    pub collapse_height: f64,
    /// Control period: one [`Hopper::step`] (s).
    pub control_period: f64,
    /// RK4 sub-steps per control period.
    pub substeps: u32,
    /// Episode duration (s).
    pub episode_duration: f64,
    /// Series-elastic actuation of both joints ([`SeaConfig`]), or `None`: the commanded joint
    /// torques act directly on the joints (the rigid, ideal torque source of
    /// [`HopperConfig::SCARLETH`]).
    pub series_elasticity: Option<SeaConfig>,
}

impl HopperConfig {
    /// The ScarlETH-like leg over the paper's random blocks (see the module docs).
    pub const SCARLETH: Self = Self {
        gravity: 9.81,
        body_mass: 3.5,
        thigh_mass: 0.5,
        shank_mass: 0.2,
        thigh_length: 0.2,
        shank_length: 0.2,
        thigh_com: 0.05,
        shank_com: 0.1,
        thigh_inertia: 0.5 * 0.2 * 0.2 / 12.0,
        shank_inertia: 0.2 * 0.2 * 0.2 / 12.0,
        armature: [0.01, 0.01],
        torque_limit: [30.0, 30.0],
        hip_range: [-1.2, 1.2],
        knee_range: [-2.5, -0.1],
        limit_stiffness: 300.0,
        limit_damping: 3.0,
        contact: Contact::RUBBER_FOOT_ON_WOOD,
        tangential_stiffness: 5.0e4,
        tangential_damping: 200.0,
        friction: 0.8,
        ground_heights: BLOCK_HEIGHTS,
        change_probability: 1.0,
        initial_height: 0.6,
        initial_knee: -1.2,
        collapse_height: 0.15,
        control_period: 1e-3,
        substeps: 4,
        episode_duration: 12.0,
        series_elasticity: None,
    };

    /// The same leg with series-elastic joints ([`SeaConfig::SCARLETH`], see the module docs):
    /// the reflected actuator inertia moves to the motor side of the springs (a 0.001 kg·m²
    /// output-side inertia stays on each joint), 8 RK4 sub-steps per control period.
    pub const SCARLETH_SEA: Self = Self {
        armature: [0.001, 0.001],
        substeps: 8,
        series_elasticity: Some(SeaConfig::SCARLETH),
        ..Self::SCARLETH
    };

    /// The same leg on flat ground (height 0, never changed).
    pub const fn flat() -> Self {
        Self {
            ground_heights: &[0.0],
            ..Self::SCARLETH
        }
    }

    /// The hip angle that puts the foot directly under the hip for knee angle `knee`:
    /// atan2(−l₂ sin q_k, l₁ + l₂ cos q_k) (= −q_k/2 for equal segments). The paper's hip
    /// reference "constrained by the leg configuration given" the knee reference.
    pub fn hip_angle_for_foot_under_hip(&self, knee: f64) -> f64 {
        (-self.shank_length * knee.sin()).atan2(self.thigh_length + self.shank_length * knee.cos())
    }

    /// Hip-to-foot distance for knee angle `knee` (m).
    pub fn leg_length(&self, knee: f64) -> f64 {
        let (l1, l2) = (self.thigh_length, self.shank_length);
        (l1 * l1 + l2 * l2 + 2.0 * l1 * l2 * knee.cos()).sqrt()
    }

    /// Total mass (kg).
    pub fn total_mass(&self) -> f64 {
        self.body_mass + self.thigh_mass + self.shank_mass
    }

    /// `Ok` when every parameter is physically meaningful, else the name of the first bad one.
    pub fn validate(&self) -> Result<(), &'static str> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let non_neg = |v: f64| v.is_finite() && v >= 0.0;
        let range = |r: [f64; 2]| r[0].is_finite() && r[1].is_finite() && r[0] < r[1];
        self.contact.validate()?;
        let checks: [(bool, &'static str); 26] = [
            (pos(self.gravity), "gravity"),
            (pos(self.body_mass), "body_mass"),
            (pos(self.thigh_mass), "thigh_mass"),
            (pos(self.shank_mass), "shank_mass"),
            (pos(self.thigh_length), "thigh_length"),
            (pos(self.shank_length), "shank_length"),
            (non_neg(self.thigh_com), "thigh_com"),
            (non_neg(self.shank_com), "shank_com"),
            (non_neg(self.thigh_inertia), "thigh_inertia"),
            (non_neg(self.shank_inertia), "shank_inertia"),
            (self.armature.iter().all(|&a| non_neg(a)), "armature"),
            (self.torque_limit.iter().all(|&t| pos(t)), "torque_limit"),
            (range(self.hip_range), "hip_range"),
            (range(self.knee_range), "knee_range"),
            (non_neg(self.limit_stiffness), "limit_stiffness"),
            (non_neg(self.limit_damping), "limit_damping"),
            (pos(self.tangential_stiffness), "tangential_stiffness"),
            (non_neg(self.tangential_damping), "tangential_damping"),
            (non_neg(self.friction), "friction"),
            (
                !self.ground_heights.is_empty()
                    && self.ground_heights.iter().all(|h| h.is_finite()),
                "ground_heights",
            ),
            (
                (0.0..=1.0).contains(&self.change_probability),
                "change_probability",
            ),
            (self.initial_height.is_finite(), "initial_height"),
            (self.initial_knee.is_finite(), "initial_knee"),
            (self.collapse_height.is_finite(), "collapse_height"),
            (pos(self.control_period), "control_period"),
            (pos(self.episode_duration), "episode_duration"),
        ];
        if let Some((_, name)) = checks.iter().find(|(ok, _)| !ok) {
            return Err(name);
        }
        if self.substeps == 0 {
            return Err("substeps");
        }
        match self.series_elasticity {
            Some(sea) => sea.validate(),
            None => Ok(()),
        }
    }
}

impl Default for HopperConfig {
    fn default() -> Self {
        Self::SCARLETH
    }
}

/// The normal force of the foot on the ground as a function of the penetration δ = h_g − y_f
/// (m) and its rate δ̇ (m/s, positive while the foot sinks in). Zero out of contact (δ ≤ 0),
/// never pulling. See the module docs, "Contact", for the laws and where the numbers come
/// from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Contact {
    /// N = max(0, k δ + c δ̇): the Kelvin–Voigt spring–damper the plant used first. Its
    /// damper acts at δ = 0, so the force jumps to c·v at touchdown and pulls (is clipped to
    /// 0) before lift-off. Kept for comparison.
    LinearSpringDamper {
        /// k (N/m).
        stiffness: f64,
        /// c (N·s/m).
        damping: f64,
    },
    /// N = max(0, k δⁿ + λ δⁿ δ̇) (Hunt & Crossley 1975; Marhefka & Orin 1999, eq. 2): the
    /// damping grows with the penetration, so the force is 0 at touchdown whatever the speed
    /// and continuous through the contact.
    HuntCrossley {
        /// k (N/mⁿ).
        stiffness: f64,
        /// n: 1.5 for a Hertzian (sphere on a plane) contact, 1 for a flat one.
        exponent: f64,
        /// λ (N·s/mⁿ⁺¹); [`Contact::hertz`] sets λ = 3/2 α k.
        damping: f64,
    },
}

impl Contact {
    /// The linear ground the plant first used (assumptions): k = 5·10⁴ N/m, c = 200 N·s/m.
    pub const LINEAR_SPRING_DAMPER: Self = Self::LinearSpringDamper {
        stiffness: 5.0e4,
        damping: 200.0,
    };

    /// A rubber ball foot of radius R = 3 cm on wood (the module docs give the derivation):
    /// Hertz stiffness k = 4/3 E* √R = 1.5·10⁶ N/m^1.5 (E* = 6.7 MPa: rubber E ≈ 5 MPa,
    /// ν = 0.5, on a much stiffer wood), α = 0.2 s/m (e ≈ 1 − α v ≈ 0.6 at the 2 m/s of a
    /// touchdown from the 0.6 m apex).
    pub const RUBBER_FOOT_ON_WOOD: Self = Self::hertz(1.5e6, 0.2);

    /// Hunt–Crossley with the Hertzian exponent n = 3/2 and λ = 3/2 α k (Marhefka & Orin
    /// 1999, eq. 12), α (s/m) setting the coefficient of restitution e ≈ 1 − α v at impact
    /// speed v.
    pub const fn hertz(stiffness: f64, alpha: f64) -> Self {
        Self::HuntCrossley {
            stiffness,
            exponent: 1.5,
            damping: 1.5 * alpha * stiffness,
        }
    }

    /// The normal force (N) at penetration `depth` (m) and penetration rate `rate` (m/s,
    /// positive sinking in): 0 when `depth` ≤ 0, never negative.
    pub fn normal_force(&self, depth: f64, rate: f64) -> f64 {
        if depth <= 0.0 {
            return 0.0;
        }
        match *self {
            Self::LinearSpringDamper { stiffness, damping } => {
                (stiffness * depth + damping * rate).max(0.0)
            }
            Self::HuntCrossley {
                stiffness,
                exponent,
                damping,
            } => {
                let d = depth.powf(exponent);
                (stiffness * d + damping * d * rate).max(0.0)
            }
        }
    }

    /// The spring part of the force at `depth` (N; 0 out of contact): the static load, used
    /// for the friction cone of the stick spring.
    pub fn elastic_force(&self, depth: f64) -> f64 {
        if depth <= 0.0 {
            return 0.0;
        }
        match *self {
            Self::LinearSpringDamper { stiffness, .. } => stiffness * depth,
            Self::HuntCrossley {
                stiffness,
                exponent,
                ..
            } => stiffness * depth.powf(exponent),
        }
    }

    /// The penetration (m) at which the spring part carries `load` (N): the static sinkage.
    pub fn static_depth(&self, load: f64) -> f64 {
        match *self {
            Self::LinearSpringDamper { stiffness, .. } => load / stiffness,
            Self::HuntCrossley {
                stiffness,
                exponent,
                ..
            } => (load / stiffness).powf(1.0 / exponent),
        }
    }

    /// The same law with the stiffness k scaled by `stiffness` and the dissipation by
    /// `damping`: c for the linear law; α = λ/(3/2 k) for Hunt–Crossley (λ scales by both,
    /// so the restitution at a given speed depends on `damping` only).
    pub fn scaled(&self, stiffness: f64, damping: f64) -> Self {
        match *self {
            Self::LinearSpringDamper {
                stiffness: k,
                damping: c,
            } => Self::LinearSpringDamper {
                stiffness: k * stiffness,
                damping: c * damping,
            },
            Self::HuntCrossley {
                stiffness: k,
                exponent,
                damping: l,
            } => Self::HuntCrossley {
                stiffness: k * stiffness,
                exponent,
                damping: l * stiffness * damping,
            },
        }
    }

    /// `Ok` for finite parameters with k > 0, damping ≥ 0 and 1 ≤ n ≤ 2; else the name of
    /// the bad one.
    pub fn validate(&self) -> Result<(), &'static str> {
        let (k, c, n) = match *self {
            Self::LinearSpringDamper { stiffness, damping } => (stiffness, damping, 1.0),
            Self::HuntCrossley {
                stiffness,
                exponent,
                damping,
            } => (stiffness, damping, exponent),
        };
        if !(k.is_finite() && k > 0.0) {
            Err("contact.stiffness")
        } else if !(c.is_finite() && c >= 0.0) {
            Err("contact.damping")
        } else if !(1.0..=2.0).contains(&n) {
            Err("contact.exponent")
        } else {
            Ok(())
        }
    }
}

/// Series-elastic actuation of a joint (both joints use the same): a motor behind a gear,
/// seen from the joint as a rotor of reflected inertia `rotor_inertia` at angle θ, coupled to
/// the joint angle q by a torsion spring; a cascaded, motor-velocity-based torque loop drives
/// the motor (see the module docs for the equations and where the numbers come from).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeaConfig {
    /// Spring stiffness k between motor and joint (N·m/rad, joint side).
    pub stiffness: f64,
    /// Spring damping b (N·m·s/rad).
    pub damping: f64,
    /// Reflected rotor and gear inertia B on the motor side of the spring (kg·m²).
    pub rotor_inertia: f64,
    /// Bandwidth f_τ of the torque loop (Hz): the spring torque follows the command as a
    /// first-order lag of time constant 1/(2π f_τ) while the motor is not saturated.
    pub torque_bandwidth: f64,
    /// Bandwidth f_v of the inner motor-velocity loop (Hz).
    pub velocity_bandwidth: f64,
    /// Motor torque limit, reflected to the joint (N·m).
    pub motor_torque_limit: f64,
}

impl SeaConfig {
    /// Our ScarlETH-like actuator (assumptions, see the module docs): k = 100 N·m/rad,
    /// b = 0.1 N·m·s/rad, B = 0.01 kg·m², f_τ = 20 Hz, f_v = 100 Hz, motor limit 30 N·m.
    pub const SCARLETH: Self = Self {
        stiffness: 100.0,
        damping: 0.1,
        rotor_inertia: 0.01,
        torque_bandwidth: 20.0,
        velocity_bandwidth: 100.0,
        motor_torque_limit: 30.0,
    };

    /// `Ok` when every parameter is physically meaningful, else the name of the first bad one.
    pub fn validate(&self) -> Result<(), &'static str> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let checks: [(bool, &'static str); 6] = [
            (pos(self.stiffness), "series_elasticity.stiffness"),
            (
                self.damping.is_finite() && self.damping >= 0.0,
                "series_elasticity.damping",
            ),
            (pos(self.rotor_inertia), "series_elasticity.rotor_inertia"),
            (
                pos(self.torque_bandwidth),
                "series_elasticity.torque_bandwidth",
            ),
            (
                pos(self.velocity_bandwidth),
                "series_elasticity.velocity_bandwidth",
            ),
            (
                pos(self.motor_torque_limit),
                "series_elasticity.motor_torque_limit",
            ),
        ];
        match checks.iter().find(|(ok, _)| !ok) {
            Some((_, name)) => Err(name),
            None => Ok(()),
        }
    }

    /// [spring torque on the joint, motor torque] for joint angle/rate `q`, `qd`, motor
    /// angle/rate `th`, `thd` and commanded joint torque `command`. The motor torque is
    /// limited to ±`motor_torque_limit`; the second value says whether it was.
    pub fn torques(&self, q: f64, qd: f64, th: f64, thd: f64, command: f64) -> ([f64; 2], bool) {
        let deflection = th - q;
        let spring = self.stiffness * deflection + self.damping * (thd - qd);
        // The deflection sensor measures k·φ (no damping term).
        let measured = self.stiffness * deflection;
        let w_t = core::f64::consts::TAU * self.torque_bandwidth;
        let w_v = core::f64::consts::TAU * self.velocity_bandwidth;
        let velocity_ref = qd + w_t * (command - measured) / self.stiffness;
        let motor = measured + self.rotor_inertia * w_v * (velocity_ref - thd);
        let lim = self.motor_torque_limit;
        ([spring, motor.clamp(-lim, lim)], motor.abs() > lim)
    }
}

/// What the leg's sensors see (and, for logging, the ground height they do not see).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HopperState {
    /// Body (hip joint) height above the world floor z = 0 (m).
    pub body_height: f64,
    /// Body vertical velocity (m/s, up positive).
    pub body_velocity: f64,
    /// [hip, knee] angles (rad); knee negative when flexed.
    pub joint_angles: [f64; 2],
    /// [hip, knee] rates (rad/s).
    pub joint_velocities: [f64; 2],
    /// Whether the foot touches the ground.
    pub contact: bool,
    /// Time since the start of the episode (s).
    pub time: f64,
    /// Current ground height under the foot (m). Not perceived by the robot: logging only.
    pub ground_height: f64,
}

/// Per-episode book-keeping for the hopping cost (energy and limit terms), reset by
/// [`Hopper::reset`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HopperStats {
    /// ∫ Σ |τ_i q̇_i| dt over the episode: absolute mechanical work of the joints (J).
    pub absolute_work: f64,
    /// ∫ Σ τ_i² dt: a copper-loss proxy (N²·m²·s).
    pub torque_squared: f64,
    /// Control steps in which a commanded torque exceeded its limit.
    pub torque_limit_steps: u32,
    /// ∫ Σ max(0, |τ_cmd,i| − τ_max,i) dt: how far beyond the limit (N·m·s).
    pub torque_excess: f64,
    /// Control steps ending with a joint inside a joint-limit stop.
    pub joint_limit_steps: u32,
    /// Apexes detected (one per hop).
    pub hops: u32,
    /// Lowest body height above the ground seen (m).
    pub min_clearance: f64,
    /// Control steps in which a series-elastic motor hit its torque limit (0 without series
    /// elasticity).
    pub motor_limit_steps: u32,
}

/// The hopping-leg plant (see the [module docs](self)).
#[derive(Debug, Clone)]
pub struct Hopper {
    config: HopperConfig,
    seed: u64,
    rng: Xoshiro256PlusPlus,
    /// [y, q_h, q_k, ẏ, q̇_h, q̇_k, θ_h, θ_k, θ̇_h, θ̇_k] (θ: motor angles, used only with
    /// series elasticity; they start at the joint angles and stay there otherwise).
    x: [f64; 10],
    /// Where the foot stuck at touchdown (x), moved when it slips; `None` in flight.
    anchor: Option<f64>,
    time: f64,
    steps: usize,
    ground: f64,
    applied: [f64; 2],
    apexes: Vec<f64>,
    new_apex: Option<f64>,
    collapsed: bool,
    stats: HopperStats,
}

impl Hopper {
    /// A plant at the start of an episode. Panics if `config` does not
    /// [validate](HopperConfig::validate) (host harness: a bad config is a bug in the test).
    pub fn new(config: HopperConfig, seed: u64) -> Self {
        if let Err(field) = config.validate() {
            panic!("invalid HopperConfig: {field}");
        }
        let mut hopper = Self {
            config,
            seed,
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            x: [0.0; 10],
            anchor: None,
            time: 0.0,
            steps: 0,
            ground: 0.0,
            applied: [0.0; 2],
            apexes: Vec::new(),
            new_apex: None,
            collapsed: false,
            stats: HopperStats::default(),
        };
        hopper.reset();
        hopper
    }

    /// Back to the start: at rest at [`HopperConfig::initial_height`] with the knee at
    /// [`HopperConfig::initial_knee`] and the foot under the hip, on the first ground height,
    /// time 0, statistics and apex list cleared. The random stream continues, so successive
    /// episodes see different block sequences; [`Hopper::new`] replays from the seed.
    pub fn reset(&mut self) {
        let c = self.config;
        let knee = c.initial_knee;
        let hip = c.hip_angle_for_foot_under_hip(knee);
        self.x = [
            c.initial_height,
            hip,
            knee,
            0.0,
            0.0,
            0.0,
            hip,
            knee,
            0.0,
            0.0,
        ];
        self.anchor = None;
        self.time = 0.0;
        self.steps = 0;
        self.ground = c.ground_heights[0];
        self.applied = [0.0; 2];
        self.apexes.clear();
        self.new_apex = None;
        self.collapsed = false;
        self.stats = HopperStats {
            min_clearance: c.initial_height - self.ground,
            ..HopperStats::default()
        };
    }

    /// The configuration in use.
    pub fn config(&self) -> &HopperConfig {
        &self.config
    }

    /// The seed given to [`Hopper::new`].
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The current state.
    pub fn state(&self) -> HopperState {
        HopperState {
            body_height: self.x[0],
            body_velocity: self.x[3],
            joint_angles: [self.x[1], self.x[2]],
            joint_velocities: [self.x[4], self.x[5]],
            contact: self.foot_height() < self.ground,
            time: self.time,
            ground_height: self.ground,
        }
    }

    /// Foot height above the world floor (m).
    pub fn foot_height(&self) -> f64 {
        let c = &self.config;
        self.x[0]
            - c.thigh_length * self.x[1].cos()
            - c.shank_length * (self.x[1] + self.x[2]).cos()
    }

    /// Foot position: [x relative to the hip (m, +x forward), height above the world floor (m)].
    pub fn foot_position(&self) -> [f64; 2] {
        [self.foot_x(), self.foot_height()]
    }

    /// The joint torques applied during the last step, after saturation (N·m). With series
    /// elasticity, the saturated *command* to the torque loops; what the springs apply is
    /// [`Hopper::joint_torques`].
    pub fn applied_torques(&self) -> [f64; 2] {
        self.applied
    }

    /// The torques acting on the joints now (N·m): the last [`Hopper::applied_torques`]
    /// without series elasticity, the spring torques k φ + b φ̇ with it.
    pub fn joint_torques(&self) -> [f64; 2] {
        self.actuation(&self.x, self.applied).0
    }

    /// [hip, knee] motor angles θ (rad, reflected to the joint; the joint angles without
    /// series elasticity).
    pub fn motor_angles(&self) -> [f64; 2] {
        match self.config.series_elasticity {
            Some(_) => [self.x[6], self.x[7]],
            None => [self.x[1], self.x[2]],
        }
    }

    /// [hip, knee] motor rates θ̇ (rad/s, reflected to the joint; the joint rates without
    /// series elasticity).
    pub fn motor_velocities(&self) -> [f64; 2] {
        match self.config.series_elasticity {
            Some(_) => [self.x[8], self.x[9]],
            None => [self.x[4], self.x[5]],
        }
    }

    /// The control period (s).
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

    /// Body heights at every flight apex of this episode so far (m), one per hop.
    pub fn apex_heights(&self) -> &[f64] {
        &self.apexes
    }

    /// The apex detected during the last [`Hopper::step`], if any (for per-tick cost shapers).
    pub fn new_apex(&self) -> Option<f64> {
        self.new_apex
    }

    /// Whether the body has come within [`HopperConfig::collapse_height`] of the ground this
    /// episode (the leg folded: a fall for this constrained robot).
    pub fn collapsed(&self) -> bool {
        self.collapsed
    }

    /// Energy and limit book-keeping for this episode.
    pub fn stats(&self) -> HopperStats {
        self.stats
    }

    /// Advances one control period with the joint torques `joint_torques` = [hip, knee] (N·m)
    /// held constant. Each is saturated to its limit (the excess is counted in
    /// [`HopperStats`]); a non-finite torque is applied as 0 and counted as a limit violation,
    /// so the state always stays finite.
    pub fn step(&mut self, joint_torques: [f64; 2]) {
        let c = self.config;
        let h = c.control_period / f64::from(c.substeps);
        let mut over = false;
        let tau: [f64; 2] = core::array::from_fn(|i| {
            let t = joint_torques[i];
            let lim = c.torque_limit[i];
            if !t.is_finite() {
                over = true;
                self.stats.torque_excess += lim * c.control_period;
                0.0
            } else {
                if t.abs() > lim {
                    over = true;
                    self.stats.torque_excess += (t.abs() - lim) * c.control_period;
                }
                t.clamp(-lim, lim)
            }
        });
        if over {
            self.stats.torque_limit_steps += 1;
        }
        self.applied = tau;
        let rising = self.x[3] > 0.0;
        let mut motor_saturated = false;
        for _ in 0..c.substeps {
            let x0 = self.x;
            let k1 = self.derivative(&x0, tau);
            let k2 = self.derivative(&axpy(&x0, 0.5 * h, &k1), tau);
            let k3 = self.derivative(&axpy(&x0, 0.5 * h, &k2), tau);
            let k4 = self.derivative(&axpy(&x0, h, &k3), tau);
            for i in 0..10 {
                self.x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
            self.update_anchor();
            let (joint, saturated) = self.actuation(&self.x, tau);
            motor_saturated |= saturated;
            for (i, t) in joint.iter().enumerate() {
                self.stats.absolute_work += h * (t * self.x[4 + i]).abs();
            }
        }
        if motor_saturated {
            self.stats.motor_limit_steps += 1;
        }
        for t in tau {
            self.stats.torque_squared += t * t * c.control_period;
        }
        self.time += c.control_period;
        self.steps += 1;
        let (hip, knee) = (self.x[1], self.x[2]);
        if hip < c.hip_range[0]
            || hip > c.hip_range[1]
            || knee < c.knee_range[0]
            || knee > c.knee_range[1]
        {
            self.stats.joint_limit_steps += 1;
        }
        let clearance = self.x[0] - self.ground;
        self.stats.min_clearance = self.stats.min_clearance.min(clearance);
        if clearance < c.collapse_height {
            self.collapsed = true;
        }
        // Apex: the body stops rising while the foot is off the ground.
        self.new_apex = None;
        if rising && self.x[3] <= 0.0 && self.foot_height() > self.ground {
            let apex = self.x[0];
            self.apexes.push(apex);
            self.new_apex = Some(apex);
            self.stats.hops += 1;
            self.maybe_change_ground();
        }
    }

    /// Foot horizontal position relative to the hip (m).
    fn foot_x(&self) -> f64 {
        let c = &self.config;
        c.thigh_length * self.x[1].sin() + c.shank_length * (self.x[1] + self.x[2]).sin()
    }

    /// Stick–slip book-keeping after a sub-step: the anchor is set at touchdown, dropped at
    /// lift-off, and dragged along when the stick spring would exceed the friction cone.
    fn update_anchor(&mut self) {
        let c = self.config;
        let depth = self.ground - self.foot_height();
        if depth <= 0.0 {
            self.anchor = None;
            return;
        }
        let xf = self.foot_x();
        let anchor = *self.anchor.get_or_insert(xf);
        let limit = c.friction * c.contact.elastic_force(depth) / c.tangential_stiffness;
        let stretch = xf - anchor;
        if stretch.abs() > limit {
            self.anchor = Some(xf - stretch.signum() * limit);
        }
    }

    fn maybe_change_ground(&mut self) {
        let c = self.config;
        if c.ground_heights.len() < 2 || c.change_probability == 0.0 {
            return;
        }
        let highest = c
            .ground_heights
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        if self.foot_height() <= highest {
            return; // a block cannot be slid under a foot that is not above it
        }
        if unit(&mut self.rng) < c.change_probability {
            let i = (self.rng.next_u64() % c.ground_heights.len() as u64) as usize;
            self.ground = c.ground_heights[i];
        }
    }

    /// The joint torques in state `x` under the commanded torques `tau`: `tau` itself without
    /// series elasticity, else the spring torques; and whether a motor is at its limit.
    fn actuation(&self, x: &[f64; 10], tau: [f64; 2]) -> ([f64; 2], bool) {
        match self.config.series_elasticity {
            None => (tau, false),
            Some(sea) => {
                let mut saturated = false;
                let joint = core::array::from_fn(|j| {
                    let (t, sat) = sea.torques(x[1 + j], x[4 + j], x[6 + j], x[8 + j], tau[j]);
                    saturated |= sat;
                    t[0]
                });
                (joint, saturated)
            }
        }
    }

    /// ẋ for state x under commanded joint torques tau.
    fn derivative(&self, x: &[f64; 10], tau: [f64; 2]) -> [f64; 10] {
        let c = &self.config;
        // Joint torques and motor accelerations B θ̈ = τ_m − τ_s (zero without elasticity).
        let (tau, motor_acc) = match c.series_elasticity {
            None => (tau, [0.0; 2]),
            Some(sea) => {
                let mut acc = [0.0; 2];
                let joint = core::array::from_fn(|j| {
                    let (t, _) = sea.torques(x[1 + j], x[4 + j], x[6 + j], x[8 + j], tau[j]);
                    acc[j] = (t[1] - t[0]) / sea.rotor_inertia;
                    t[0]
                });
                (joint, acc)
            }
        };
        let (q1, q2) = (x[1], x[2]);
        let (yd, q1d, q2d) = (x[3], x[4], x[5]);
        let a = q1 + q2;
        let ad = q1d + q2d;
        let (s1, c1) = q1.sin_cos();
        let (sa, ca) = a.sin_cos();
        let (l1, l2, r1, r2) = (c.thigh_length, c.shank_length, c.thigh_com, c.shank_com);
        let (m1, m2) = (c.thigh_mass, c.shank_mass);
        // Jacobians (rows: x, y) of the thigh and shank centres of mass and of the foot.
        let j1 = [[0.0, r1 * c1, 0.0], [1.0, r1 * s1, 0.0]];
        let j2 = [
            [0.0, l1 * c1 + r2 * ca, r2 * ca],
            [1.0, l1 * s1 + r2 * sa, r2 * sa],
        ];
        let jf = [
            [0.0, l1 * c1 + l2 * ca, l2 * ca],
            [1.0, l1 * s1 + l2 * sa, l2 * sa],
        ];
        // J̇ q̇ of the two centres of mass (centripetal terms).
        let a1 = [-r1 * s1 * q1d * q1d, r1 * c1 * q1d * q1d];
        let a2 = [
            -l1 * s1 * q1d * q1d - r2 * sa * ad * ad,
            l1 * c1 * q1d * q1d + r2 * ca * ad * ad,
        ];
        let mut m = [[0.0; 3]; 3];
        m[0][0] = c.body_mass;
        for r in 0..3 {
            for s in 0..3 {
                for k in 0..2 {
                    m[r][s] += m1 * j1[k][r] * j1[k][s] + m2 * j2[k][r] * j2[k][s];
                }
            }
        }
        // Rotational inertia: thigh ω = q̇_h, shank ω = q̇_h + q̇_k; plus actuator inertia.
        m[1][1] += c.thigh_inertia + c.shank_inertia + c.armature[0];
        m[1][2] += c.shank_inertia;
        m[2][1] += c.shank_inertia;
        m[2][2] += c.shank_inertia + c.armature[1];
        // Right-hand side: τ + gravity + contact + joint stops − bias.
        let g = c.gravity;
        let mut rhs = [0.0, tau[0], tau[1]];
        for r in 0..3 {
            rhs[r] -= g * (m1 * j1[1][r] + m2 * j2[1][r]);
            rhs[r] -= m1 * (j1[0][r] * a1[0] + j1[1][r] * a1[1]);
            rhs[r] -= m2 * (j2[0][r] * a2[0] + j2[1][r] * a2[1]);
        }
        rhs[0] -= g * c.body_mass;
        let foot_y = x[0] - l1 * c1 - l2 * ca;
        let depth = self.ground - foot_y;
        if depth > 0.0 {
            let foot_yd = yd + jf[1][1] * q1d + jf[1][2] * q2d;
            let normal = c.contact.normal_force(depth, -foot_yd);
            let foot_x = l1 * s1 + l2 * sa;
            let foot_xd = jf[0][1] * q1d + jf[0][2] * q2d;
            let anchor = self.anchor.unwrap_or(foot_x);
            let cap = c.friction * normal;
            let tangential = (-c.tangential_stiffness * (foot_x - anchor)
                - c.tangential_damping * foot_xd)
                .clamp(-cap, cap);
            for r in 0..3 {
                rhs[r] += jf[1][r] * normal + jf[0][r] * tangential;
            }
        }
        rhs[1] += stop(q1, q1d, c.hip_range, c.limit_stiffness, c.limit_damping);
        rhs[2] += stop(q2, q2d, c.knee_range, c.limit_stiffness, c.limit_damping);
        let qdd = solve3(&m, &rhs);
        [
            yd,
            q1d,
            q2d,
            qdd[0],
            qdd[1],
            qdd[2],
            x[8],
            x[9],
            motor_acc[0],
            motor_acc[1],
        ]
    }
}

/// Torque of a joint-limit stop: a one-sided spring–damper outside [lo, hi], never pulling
/// the joint into the stop.
fn stop(q: f64, qd: f64, range: [f64; 2], k: f64, c: f64) -> f64 {
    if q < range[0] {
        (k * (range[0] - q) - c * qd).max(0.0)
    } else if q > range[1] {
        (-k * (q - range[1]) - c * qd).min(0.0)
    } else {
        0.0
    }
}

/// x + a·y.
fn axpy(x: &[f64; 10], a: f64, y: &[f64; 10]) -> [f64; 10] {
    core::array::from_fn(|i| x[i] + a * y[i])
}

/// Solves the symmetric positive-definite 3×3 system m·v = b by Cholesky.
fn solve3(m: &[[f64; 3]; 3], b: &[f64; 3]) -> [f64; 3] {
    let l00 = m[0][0].sqrt();
    let l10 = m[1][0] / l00;
    let l20 = m[2][0] / l00;
    let l11 = (m[1][1] - l10 * l10).sqrt();
    let l21 = (m[2][1] - l20 * l10) / l11;
    let l22 = (m[2][2] - l20 * l20 - l21 * l21).sqrt();
    let y0 = b[0] / l00;
    let y1 = (b[1] - l10 * y0) / l11;
    let y2 = (b[2] - l20 * y0 - l21 * y1) / l22;
    let v2 = y2 / l22;
    let v1 = (y1 - l21 * v2) / l11;
    let v0 = (y0 - l10 * v1 - l20 * v2) / l00;
    [v0, v1, v2]
}

/// A uniform f64 in [0, 1) from 53 random bits.
fn unit<R: RngCore>(rng: &mut R) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The nominal (zero-correction) hopping controller: a clock-driven joint PD with constant
/// gains, tuned in simulation on flat ground for a 0.6 m apex (docs/plants.md says how;
/// `tests/hopper_tuning.rs` reproduces it).
///
/// With phase φ = (t / T) mod 1 (t from the episode start, which is an apex at rest):
///
/// ```text
/// q_k,ref(φ) = knee_mean + knee_amplitude · cos(2π (φ − phase))
/// q_h,ref(φ) = HopperConfig::hip_angle_for_foot_under_hip(q_k,ref(φ))
/// τ_j        = kp (q_j,ref − q_j) − kd q̇_j          (j = hip, knee; the same kp, kd)
/// ```
///
/// This is the paper's PD (eq. 6) with the reference rate term dropped, its hip reference
/// "constrained by the leg configuration given" the knee reference, and constant gains. The
/// learned policy of the paper adds periodic corrections (10 kernels each) to q_k,ref, kp and
/// kd, and adjusts T.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NominalHopping {
    /// Hopping period T (s).
    pub period: f64,
    /// Mean knee reference (rad, negative = flexed).
    pub knee_mean: f64,
    /// Amplitude of the knee reference (rad).
    pub knee_amplitude: f64,
    /// Phase (in [0, 1)) at which the knee reference is most extended.
    pub phase: f64,
    /// Proportional gain (N·m/rad), both joints.
    pub kp: f64,
    /// Derivative gain (N·m·s/rad), both joints.
    pub kd: f64,
}

impl NominalHopping {
    /// The parameters tuned for [`HopperConfig::SCARLETH`] on flat ground (apex 0.60 m).
    pub const TUNED: Self = Self {
        period: 0.62,
        knee_mean: -1.02,
        knee_amplitude: 0.63,
        phase: 0.72,
        kp: 30.0,
        kd: 0.6,
    };

    /// The parameters tuned for [`HopperConfig::SCARLETH_SEA`] on flat ground by the procedure
    /// of `experiments/tests/hopper_tuning.rs` (motor-limit steps counted as violations too),
    /// rounded to two decimals: `cargo run --release -p experiments --example hopper_sea --
    /// --tune`.
    pub const SEA_TUNED: Self = Self {
        period: 0.67,
        knee_mean: -0.92,
        knee_amplitude: 0.50,
        phase: 0.70,
        kp: 18.0,
        kd: 0.6,
    };

    /// Phase φ = (t / T) mod 1 at time `t`.
    pub fn phase_at(&self, t: f64) -> f64 {
        (t / self.period).rem_euclid(1.0)
    }

    /// The knee reference at phase `phi`.
    pub fn knee_reference(&self, phi: f64) -> f64 {
        self.knee_mean + self.knee_amplitude * (core::f64::consts::TAU * (phi - self.phase)).cos()
    }

    /// [hip, knee] torques for `state` on a leg described by `config`.
    pub fn torques(&self, config: &HopperConfig, state: &HopperState) -> [f64; 2] {
        let knee_ref = self.knee_reference(self.phase_at(state.time));
        let refs = [config.hip_angle_for_foot_under_hip(knee_ref), knee_ref];
        core::array::from_fn(|j| {
            self.kp * (refs[j] - state.joint_angles[j]) - self.kd * state.joint_velocities[j]
        })
    }
}
