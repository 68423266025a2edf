//! The robots' own tasks as black boxes, for the side-by-side comparison with the Python
//! peers (pycma, ZOOpt, nevergrad, SafeOpt, bayesian-optimization): a [`Trial`] scores θ one
//! episode at a time, exactly as an optimizer on the robot sees it, and re-runs a returned θ
//! on fresh episodes (the *deployed* cost, the figure a user gets). The `oracle` binary serves trials over a line protocol to
//! `peers/compare.py`; [`run_library`] drives the library's optimizers on the same trials
//! in-process, so every method sees the same episodes in the same order.
//!
//! | task | n | box | start | budget | success | episodes |
//! |---|---|---|---|---|---|---|
//! | `auv` | 18 | [−1, 1] | W = 0 | 150 | cost < 1 (within D = 1 m) | the "real" plant (0.6 m/s current) with seeded disturbances; each episode continues the noise; deployed on 5 new disturbance sequences |
//! | `auv-calm` | 18 | [−1, 1] | W = 0 | 150 | cost < 1 | the same plant without disturbances: deterministic |
//! | `auv-rotated` | 18 | [−1, 1] | W = 0 | 150 | cost < 1 | `auv` with the current turned by 45° ([`ROTATED_TASK_DEG`]), as in `model_safety_auv` |
//! | `hopper` | 31 | the task's box | zero correction | 200 | cost ≤ 3·10⁻⁴ | the seed's block course, replayed every episode; deployed on 5 unseen courses |
//! | `arm` | 50 | [−10⁴, 10⁴] | minimum-jerk θ | 1,000 | cost < 1 % of the start's | deterministic |
//! | `sphere`, `ackley` | 10 | [−1, 1] | 0 | 100 | cost < 0.01 (Sphere), Ackley's value at that distance | shifted to 0.2, deterministic |
//!
//! [`Conditions`] move the AUV tasks off the conditions their settings were chosen in: warm-up
//! episodes of the bare controller before learning (every learning episode then meets the
//! disturbances drawn that many episodes later), and the current turned about the vertical.
//! [`Trial::new`] is the nominal conditions, as in the table (for `auv-rotated`, the turn of
//! [`Conditions`] adds to the task's own 45°).
//!
//! Every episode is also judged safe or unsafe ([`Scored`]): on the hopper an episode off the
//! gait, on the other tasks a cost above the bare controller's by more than
//! [`SAFETY_MARGIN`] of it ([`Trial::safe_threshold`], the bound the safe methods are given).

use std::time::Instant;

use ctrl_adapt::optimizer::{
    Bounds, CemConfig, CmaesConfig, ControlledRandomSearch, CoordinateConfig, CrsConfig,
    DiagonalCem, LineBo, LineBoConfig, Optimizer, Rockstar, RockstarConfig, Sracos, SracosConfig,
    Status, Vector, Weighting,
};
use host_tests::arm::{self, ViaPointArm};
use host_tests::auv::{Auv, AuvConfig};
use host_tests::functions::{ackley, sphere};
use host_tests::hopper::Hopper;
use host_tests::{auv_task, hopper_task};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// The dimension of the synthetic tasks.
pub const SYNTHETIC: usize = 10;

/// Fresh episodes a returned θ is re-run on for its deployed cost.
pub const DEPLOY_EPISODES: u64 = 5;

/// One of the robots' tasks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Task {
    /// The AUV survey in a current (18 parameters), with the experiments' disturbances.
    Auv,
    /// The same survey without disturbances: every episode of a θ is the same, and the
    /// quantised survey cost (time within D in 0.1 s steps) has plateaus.
    AuvCalm,
    /// The disturbed survey with the current turned by [`ROTATED_TASK_DEG`] (the changed
    /// current of the model-based learner's study, `examples/model_safety_auv.rs`).
    AuvRotated,
    /// The hopping leg on uneven ground (31 parameters).
    Hopper,
    /// The 10-link via-point arm (50 parameters).
    Arm,
    /// Sphere shifted to 0.2 on [−1, 1]¹⁰ (the SRACOS paper's synthetic set-up).
    Sphere,
    /// Ackley shifted to 0.2 on [−1, 1]¹⁰.
    Ackley,
}

impl Task {
    /// Every task, in table order.
    pub const ALL: [Self; 7] = [
        Self::Auv,
        Self::AuvCalm,
        Self::AuvRotated,
        Self::Hopper,
        Self::Arm,
        Self::Sphere,
        Self::Ackley,
    ];

    /// The task named `name` (`auv`, `auv-calm`, `auv-rotated`, `hopper`, `arm`, `sphere`,
    /// `ackley`).
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Its name in the protocol and the table.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auv => "auv",
            Self::AuvCalm => "auv-calm",
            Self::AuvRotated => "auv-rotated",
            Self::Hopper => "hopper",
            Self::Arm => "arm",
            Self::Sphere => "sphere",
            Self::Ackley => "ackley",
        }
    }

    /// The number of parameters.
    pub fn dimension(self) -> usize {
        match self {
            Self::Auv | Self::AuvCalm | Self::AuvRotated => auv_task::P,
            Self::Hopper => hopper_task::P,
            Self::Arm => arm::PARAMS,
            Self::Sphere | Self::Ackley => SYNTHETIC,
        }
    }

    /// The episode budget of the comparison.
    pub fn budget(self) -> u32 {
        match self {
            Self::Auv | Self::AuvCalm | Self::AuvRotated => 150,
            Self::Hopper => 200,
            Self::Arm => 1000,
            Self::Sphere | Self::Ackley => 10 * SYNTHETIC as u32,
        }
    }
}

/// The turn of the current in the `auv-rotated` task (degrees, from +x towards +y): the
/// changed current of `examples/model_safety_auv.rs` and of the guard study.
pub const ROTATED_TASK_DEG: f64 = 45.0;

/// Conditions of an AUV trial other than the nominal ones of [`Trial::new`], to check a
/// setting away from the conditions it was chosen in. Only the AUV tasks (`auv`,
/// `auv-calm`, `auv-rotated`) read them; the other tasks ignore them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditions {
    /// Episodes of the bare controller (the start θ) run on the plant when the trial is
    /// built, before the first learning episode and not counted as evaluations: the
    /// disturbances (noise and turbulence, which continue from episode to episode) of
    /// learning episode k are those the nominal trial draws in episode k + `warm_up`. The
    /// bare controller's cost ([`Trial::start_cost`]) is then its first episode after them.
    pub warm_up: u32,
    /// The current's direction turned about the vertical by this angle (degrees; +90 turns
    /// +x into +y); its speed and depth as in `AuvConfig::REAL`.
    pub current_rotation_deg: f64,
}

impl Conditions {
    /// The conditions of [`Trial::new`].
    pub const NOMINAL: Self = Self {
        warm_up: 0,
        current_rotation_deg: 0.0,
    };
    /// One warm-up episode before learning.
    pub const WARM_UP: Self = Self {
        warm_up: 1,
        ..Self::NOMINAL
    };
    /// The current turned by 30° (from +x towards +y).
    pub const ROTATED: Self = Self {
        current_rotation_deg: 30.0,
        ..Self::NOMINAL
    };

    /// The conditions named `name`: `nominal`, `warm-up`, `rotated`, or `warm-up:K` and
    /// `rotated:DEGREES` for other amounts.
    pub fn parse(name: &str) -> Option<Self> {
        match name.split_once(':') {
            Some(("warm-up", k)) => Some(Self {
                warm_up: k.parse().ok()?,
                ..Self::NOMINAL
            }),
            Some(("rotated", deg)) => Some(Self {
                current_rotation_deg: deg.parse().ok().filter(|d: &f64| d.is_finite())?,
                ..Self::NOMINAL
            }),
            Some(_) => None,
            None => match name {
                "nominal" => Some(Self::NOMINAL),
                "warm-up" => Some(Self::WARM_UP),
                "rotated" => Some(Self::ROTATED),
                _ => None,
            },
        }
    }
}

/// The episodes of one task and seed.
enum Episodes {
    Auv(Box<Auv>),
    Hopper(u64),
    Arm(Box<ViaPointArm>),
    Synthetic(fn(&Vector<SYNTHETIC>, f64) -> f32),
}

/// One run's black box: the task's box, start, success threshold, and its episodes.
pub struct Trial {
    task: Task,
    seed: u64,
    conditions: Conditions,
    episodes: Episodes,
    lower: Vec<f32>,
    upper: Vec<f32>,
    start: Vec<f32>,
    threshold: f32,
    evaluations: u32,
    /// The safe methods' cost bound, computed on first use ([`Trial::safe_threshold`]).
    bound: std::cell::OnceCell<Option<f32>>,
}

/// One learning episode: its cost and whether it was unsafe ([`Trial::episode`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scored {
    /// The episode's cost.
    pub cost: f32,
    /// Unsafe: on the hopper an episode off the gait (a collapse, fewer than 15 hops, or a
    /// mean apex outside the set height's band: `HopEpisode::hops_stably`); on the other
    /// tasks a cost above [`Trial::safe_threshold`]. A θ the task rejects is unsafe.
    pub unsafe_episode: bool,
}

pub(crate) fn to_vec<const N: usize>(v: &Vector<N>) -> Vec<f32> {
    v.iter().copied().collect()
}

fn to_vector<const N: usize>(x: &[f32]) -> Option<Vector<N>> {
    (x.len() == N).then(|| Vector::from_fn(|i, _| x[i]))
}

impl Trial {
    /// The trial of `task` with seed `seed`, in the nominal conditions.
    pub fn new(task: Task, seed: u64) -> Self {
        Self::with_conditions(task, seed, Conditions::NOMINAL)
    }

    /// The trial of `task` with seed `seed` in `conditions` (read by the AUV tasks only).
    pub fn with_conditions(task: Task, seed: u64, conditions: Conditions) -> Self {
        let (episodes, lower, upper, start, threshold) = match task {
            Task::Auv | Task::AuvCalm | Task::AuvRotated => {
                let b = auv_task::bounds();
                let mut config = AuvConfig::REAL;
                let turn = conditions.current_rotation_deg
                    + if task == Task::AuvRotated {
                        ROTATED_TASK_DEG
                    } else {
                        0.0
                    };
                if turn != 0.0 {
                    let (sin, cos) = turn.to_radians().sin_cos();
                    let [x, y, z] = config.current_direction;
                    config.current_direction = [cos * x - sin * y, sin * x + cos * y, z];
                }
                let mut auv = if task == Task::AuvCalm {
                    Auv::new(config, seed)
                } else {
                    auv_task::plant(config, seed)
                };
                let bare = vec![0.0; auv_task::P];
                for _ in 0..conditions.warm_up {
                    auv_cost(
                        &bare,
                        &mut auv,
                        &mut Xoshiro128PlusPlus::seed_from_u64(seed),
                        None,
                    );
                }
                (
                    Episodes::Auv(Box::new(auv)),
                    to_vec(b.lower()),
                    to_vec(b.upper()),
                    vec![0.0; auv_task::P],
                    auv_task::RADIUS,
                )
            }
            Task::Hopper => {
                let b = hopper_task::bounds();
                (
                    Episodes::Hopper(seed),
                    to_vec(b.lower()),
                    to_vec(b.upper()),
                    vec![0.0; hopper_task::P],
                    3e-4,
                )
            }
            Task::Arm => {
                let a = ViaPointArm::new();
                let b = arm::bounds();
                let start = a.minimum_jerk_theta();
                let threshold = 0.01 * a.cost(&start);
                (
                    Episodes::Arm(Box::new(a)),
                    to_vec(b.lower()),
                    to_vec(b.upper()),
                    to_vec(&start),
                    threshold,
                )
            }
            Task::Sphere | Task::Ackley => (
                Episodes::Synthetic(if task == Task::Sphere {
                    sphere::<SYNTHETIC>
                } else {
                    ackley::<SYNTHETIC>
                }),
                vec![-1.0; SYNTHETIC],
                vec![1.0; SYNTHETIC],
                vec![0.0; SYNTHETIC],
                // Sphere: within 0.1 of the optimum; Ackley: the same distance's value.
                if task == Task::Sphere {
                    0.01
                } else {
                    ackley::<SYNTHETIC>(&Vector::repeat(0.2 + 0.1 / (SYNTHETIC as f32).sqrt()), 0.2)
                },
            ),
        };
        Self {
            task,
            seed,
            conditions,
            episodes,
            lower,
            upper,
            start,
            threshold,
            evaluations: 0,
            bound: std::cell::OnceCell::new(),
        }
    }

    /// The task.
    pub fn task(&self) -> Task {
        self.task
    }

    /// The conditions it was built in.
    pub fn conditions(&self) -> Conditions {
        self.conditions
    }

    /// The AUV tasks' plant as it is before the next episode (its disturbances continue from
    /// episode to episode); `None` on the other tasks.
    pub fn auv(&self) -> Option<&Auv> {
        match &self.episodes {
            Episodes::Auv(auv) => Some(auv),
            _ => None,
        }
    }

    /// The box's lower corner.
    pub fn lower(&self) -> &[f32] {
        &self.lower
    }

    /// The box's upper corner.
    pub fn upper(&self) -> &[f32] {
        &self.upper
    }

    /// The start θ (for methods that take one).
    pub fn start(&self) -> &[f32] {
        &self.start
    }

    /// Success: a cost below this.
    pub fn threshold(&self) -> f32 {
        self.threshold
    }

    /// The cost of the start θ in this trial's first episode, from a fresh copy of the
    /// trial (not counted as an evaluation): the bare controller's cost, the reference of
    /// the safety threshold ([`unsafe_threshold`]).
    pub fn start_cost(&self) -> Option<f32> {
        Some(
            Trial::with_conditions(self.task, self.seed, self.conditions)
                .run(&self.start, None)?
                .0,
        )
    }

    /// Episodes scored so far.
    pub fn evaluations(&self) -> u32 {
        self.evaluations
    }

    /// θ clipped into the box (peers may step a hair outside it), or `None` for a wrong
    /// length or a non-finite entry.
    fn clip(&self, x: &[f32]) -> Option<Vec<f32>> {
        (x.len() == self.lower.len() && x.iter().all(|v| v.is_finite())).then(|| {
            x.iter()
                .zip(self.lower.iter().zip(&self.upper))
                .map(|(v, (l, u))| v.max(*l).min(*u))
                .collect()
        })
    }

    /// The cost bound of the safe methods (`linebo-safe` and the Python peers' SafeOpt): the
    /// bare controller's cost ([`Trial::start_cost`]) plus [`SAFETY_MARGIN`] of its
    /// magnitude. It is also the unsafe-episode rule on every task but the hopper.
    pub fn safe_threshold(&self) -> Option<f32> {
        *self.bound.get_or_init(|| {
            let bare = self.start_cost()?;
            Some(bare + SAFETY_MARGIN * bare.abs())
        })
    }

    /// One learning episode of θ (clipped into the box): its cost. `None` for a malformed θ.
    pub fn score(&mut self, x: &[f32]) -> Option<f32> {
        self.episode(x).map(|e| e.cost)
    }

    /// One learning episode of θ (clipped into the box): its cost and whether it was unsafe
    /// (see [`Scored`]); the cost is the one [`Trial::score`] gives. `None` for a malformed θ.
    pub fn episode(&mut self, x: &[f32]) -> Option<Scored> {
        self.judged(x, None)
    }

    /// [`Trial::episode`], handing `observe` the episode's ticks for a plant model (see
    /// [`Tick`]); the synthetic tasks have none.
    pub fn episode_observed(
        &mut self,
        x: &[f32],
        observe: &mut dyn FnMut(Tick<'_>),
    ) -> Option<Scored> {
        self.judged(x, Some(observe))
    }

    fn judged(&mut self, x: &[f32], observe: Option<&mut dyn FnMut(Tick<'_>)>) -> Option<Scored> {
        let (cost, off_gait) = self.run(x, observe)?;
        let unsafe_episode = match self.task {
            Task::Hopper => off_gait,
            _ => self
                .safe_threshold()
                .is_none_or(|h| cost.is_nan() || cost > h),
        };
        Some(Scored {
            cost,
            unsafe_episode,
        })
    }

    /// One learning episode: its cost and whether it left the hopper's gait; its ticks to
    /// `observe`.
    fn run(&mut self, x: &[f32], observe: Option<&mut dyn FnMut(Tick<'_>)>) -> Option<(f32, bool)> {
        let x = self.clip(x)?;
        self.evaluations += 1;
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(self.seed);
        Some(match &mut self.episodes {
            Episodes::Auv(auv) => (auv_cost(&x, auv, &mut rng, observe), false),
            Episodes::Hopper(seed) => hopper_episode(
                &x,
                &mut hopper_task::plant(true, 1000 + *seed),
                &mut rng,
                observe,
            ),
            Episodes::Arm(a) => {
                let theta = to_vector(&x)?;
                match observe {
                    None => (a.cost(&theta), false),
                    Some(observe) => {
                        let (states, forcings, terms) = a.ticks(&theta);
                        for (k, state) in states.iter().enumerate() {
                            observe(Tick::Arm(state, forcings.get(k)));
                        }
                        (terms.total() as f32, false)
                    }
                }
            }
            Episodes::Synthetic(f) => (f(&to_vector(&x)?, 0.2), false),
        })
    }

    /// θ's mean cost over [`DEPLOY_EPISODES`] fresh episodes (not counted as evaluations):
    /// new disturbance sequences for the AUV, unseen block courses for the hopper, the same
    /// deterministic episode for the arm.
    pub fn deployed(&self, x: &[f32]) -> Option<f32> {
        let x = self.clip(x)?;
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(self.seed);
        let fresh = |k: u64| 20_000 + 100 * self.seed + k;
        let total: f32 = match &self.episodes {
            Episodes::Auv(auv) => (0..DEPLOY_EPISODES)
                .map(|k| {
                    let mut auv = Auv::new(*auv.config(), fresh(k));
                    auv_cost(&x, &mut auv, &mut rng, None)
                })
                .sum(),
            Episodes::Hopper(_) => (0..DEPLOY_EPISODES)
                .map(|k| {
                    let mut hopper = hopper_task::plant(true, fresh(k));
                    hopper_episode(&x, &mut hopper, &mut rng, None).0
                })
                .sum(),
            Episodes::Arm(a) => DEPLOY_EPISODES as f32 * a.cost(&to_vector(&x)?),
            Episodes::Synthetic(f) => DEPLOY_EPISODES as f32 * f(&to_vector(&x)?, 0.2),
        };
        Some(total / DEPLOY_EPISODES as f32)
    }
}

/// One tick of a trial's episode, for a plant model fitted on the ticks
/// ([`Trial::episode_observed`]): the plant's state before a step with the command sent to
/// it, and the state after the last step without one.
#[derive(Clone, Copy)]
pub enum Tick<'a> {
    /// The AUV and the velocity command (`host_tests::auv_task::evaluate_observed`).
    Auv(&'a Auv, Option<&'a Vector<3>>),
    /// The leg and the [knee, hip] torques (`host_tests::hopper_task::evaluate_observed`).
    Hopper(&'a Hopper, Option<&'a Vector<2>>),
    /// The arm's joint angles and scaled velocities [y, z] and the forcing terms applied
    /// from them (`ViaPointArm::ticks`).
    Arm(&'a [f64; 2 * arm::LINKS], Option<&'a [f64; arm::LINKS]>),
}

fn auv_cost(
    x: &[f32],
    auv: &mut Auv,
    rng: &mut Xoshiro128PlusPlus,
    observe: Option<&mut dyn FnMut(Tick<'_>)>,
) -> f32 {
    let theta = to_vector(x).unwrap_or_else(Vector::zeros);
    match observe {
        None => auv_task::evaluate(theta, auv, rng, false),
        Some(observe) => auv_task::evaluate_observed(theta, auv, rng, false, |a, u| {
            observe(Tick::Auv(a, u));
        }),
    }
    .map_or(f32::INFINITY, |e| e.report.cost)
}

/// A hopper episode's cost and whether it left the gait (a rejected θ: +∞ and off).
fn hopper_episode(
    x: &[f32],
    hopper: &mut Hopper,
    rng: &mut Xoshiro128PlusPlus,
    observe: Option<&mut dyn FnMut(Tick<'_>)>,
) -> (f32, bool) {
    let theta = to_vector(x).unwrap_or_else(Vector::zeros);
    match observe {
        None => hopper_task::evaluate(theta, hopper, rng, false),
        Some(observe) => hopper_task::evaluate_observed(theta, hopper, rng, |h, u| {
            observe(Tick::Hopper(h, u));
        }),
    }
    .map_or((f32::INFINITY, true), |e| (e.report.cost, !e.hops_stably()))
}

/// What one optimizer run did on a trial.
#[derive(Debug, Clone, PartialEq)]
pub struct RunReport {
    /// The cost of every episode, in order.
    pub costs: Vec<f32>,
    /// The θ the method returns (its best).
    pub returned: Vec<f32>,
    /// Mean optimizer time per evaluation (ask + tell), nanoseconds.
    pub optimizer_ns: f64,
    /// The unsafe episodes of the run ([`Scored::unsafe_episode`]).
    pub unsafe_episodes: usize,
    /// For the model-based learner, the episodes its model-free fallback proposed
    /// ([`crate::model_learner::Origin::Fallback`]); `None` for the other methods.
    pub fallback_episodes: Option<usize>,
}

impl RunReport {
    /// The first episode (1-based) below `threshold`, if any.
    pub fn first_success(&self, threshold: f32) -> Option<usize> {
        self.costs
            .iter()
            .position(|c| *c < threshold)
            .map(|k| k + 1)
    }

    /// The lowest cost of the run.
    pub fn best(&self) -> f32 {
        self.costs.iter().copied().fold(f32::INFINITY, f32::min)
    }
}

/// The library's methods of the comparison (`run_library` also knows `cem`, the sweep's
/// `DiagonalCem`, which the peer comparison does not list). `model` is the model-based
/// learner ([`crate::model_learner::run_on_trial`]; the robots' tasks only).
pub const LIBRARY_METHODS: [&str; 8] = [
    "coordinate",
    "sracos",
    "crs",
    "cmaes",
    "rockstar",
    "linebo",
    "linebo-safe",
    "model",
];

/// The safe methods' cost bound exceeds the bare controller's cost (the start's, in the
/// trial's first episode) by this fraction of its magnitude ([`Trial::safe_threshold`]).
pub const SAFETY_MARGIN: f32 = 0.2;

/// [`Trial::safe_threshold`]: the bare controller's cost plus [`SAFETY_MARGIN`] of it.
/// `linebo-safe` is given it as its threshold.
pub fn unsafe_threshold(trial: &Trial) -> Option<f32> {
    trial.safe_threshold()
}

/// LineBO's settings for a trial, by the rule of its docs: σ_f = the start's cost (a bad θ
/// can double it), σ_n = 5 % of it, the GP remembering 64 episodes (its size on the
/// microcontroller at n = 18), one episode per coordinate line (the LCB minimiser of each
/// line, then on to the next). The rest was chosen on the AUV on seeds 101–110, by a rule
/// fixed before the runs, and is reported on seeds 1–10 (`line_bo_auv`'s settings tables;
/// findings/line-bo.md): without a threshold ℓ = 0.1 of the box and β = 2; with `safe`, the
/// threshold of [`unsafe_threshold`], ℓ = 0.15 and β = 3.
pub fn line_bo_config(trial: &Trial, budget: u32, safe: bool) -> Option<LineBoConfig> {
    let scale = trial.start_cost()?.abs().max(f32::MIN_POSITIVE.sqrt());
    Some(LineBoConfig {
        signal_variance: scale * scale,
        noise_variance: (0.05 * scale) * (0.05 * scale),
        length_scale: if safe { 0.15 } else { 0.1 },
        beta: if safe { 3.0 } else { 2.0 },
        evaluations_per_line: 1,
        threshold: if safe {
            Some(unsafe_threshold(trial)?)
        } else {
            None
        },
        max_evaluations: budget,
        ..LineBoConfig::DEFAULT
    })
}

/// Runs the library method `method` (one of [`LIBRARY_METHODS`]) on `trial` for `budget`
/// episodes with the RNG seeded by `seed`; `None` for an unknown method (or `model` on a
/// synthetic task, which has no plant to model).
pub fn run_library(method: &str, trial: &mut Trial, budget: u32, seed: u64) -> Option<RunReport> {
    if method == "model" {
        return crate::model_learner::report_on_trial(trial, budget, seed);
    }
    match trial.task() {
        // λ = 4 + ⌊3 ln n⌋, CMA-ES's default population.
        Task::Auv | Task::AuvCalm | Task::AuvRotated => {
            run_n::<{ auv_task::P }, 12>(method, trial, budget, seed)
        }
        Task::Hopper => run_n::<{ hopper_task::P }, 14>(method, trial, budget, seed),
        Task::Arm => run_n::<{ arm::PARAMS }, 15>(method, trial, budget, seed),
        Task::Sphere | Task::Ackley => run_n::<SYNTHETIC, 10>(method, trial, budget, seed),
    }
}

fn run_n<const N: usize, const L: usize>(
    method: &str,
    trial: &mut Trial,
    budget: u32,
    seed: u64,
) -> Option<RunReport> {
    let bounds = Bounds::<N>::try_new(to_vector(trial.lower())?, to_vector(trial.upper())?).ok()?;
    let start: Vector<N> = to_vector(trial.start())?;
    // Steps and σ in half-widths of the box where the task has no better scale: a quarter of
    // the AUV box (the tuned local step), a sixth of the hopper's, 1 % of the arm's (σ = 100,
    // the via-point experiments' exploration).
    let fraction = match trial.task() {
        Task::Auv | Task::AuvCalm | Task::AuvRotated => 0.25,
        Task::Hopper => 1.0 / 6.0,
        Task::Arm => 0.01,
        Task::Sphere | Task::Ackley => 0.3,
    };
    let steps = (bounds.upper() - bounds.lower()) * (fraction / 2.0);
    match method {
        "coordinate" => {
            let config = CoordinateConfig {
                tolerance: 1e-3 * fraction,
                max_evaluations: budget,
                ..CoordinateConfig::DEFAULT
            };
            let o = ctrl_adapt::optimizer::CoordinateSearch::try_with_steps(
                bounds, start, steps, config,
            )
            .ok()?;
            Some(drive(o, trial, budget, seed))
        }
        "sracos" => {
            let config = SracosConfig {
                max_evaluations: budget,
                ..SracosConfig::DEFAULT
            };
            // ZOOpt's set sizes for the budget.
            Some(
                match ctrl_adapt::optimizer::sracos::zoopt_set_sizes(budget) {
                    (1, 3) => drive(
                        Sracos::<N, 1, 3>::try_new(bounds, config).ok()?,
                        trial,
                        budget,
                        seed,
                    ),
                    (1, 5) => drive(
                        Sracos::<N, 1, 5>::try_new(bounds, config).ok()?,
                        trial,
                        budget,
                        seed,
                    ),
                    (2, 10) => drive(
                        Sracos::<N, 2, 10>::try_new(bounds, config).ok()?,
                        trial,
                        budget,
                        seed,
                    ),
                    _ => drive(
                        Sracos::<N, 2, 20>::try_new(bounds, config).ok()?,
                        trial,
                        budget,
                        seed,
                    ),
                },
            )
        }
        "crs" => {
            let config = CrsConfig {
                max_evaluations: budget,
                ..CrsConfig::DEFAULT
            };
            let o = ControlledRandomSearch::<N, 100>::try_new(bounds, config).ok()?;
            Some(drive(o, trial, budget, seed))
        }
        "cmaes" => {
            let config = CmaesConfig {
                initial_sigma: fraction,
                max_evaluations: budget,
                ..CmaesConfig::DEFAULT
            };
            let o = ctrl_adapt::optimizer::Cmaes::<N, L>::try_new(bounds, start, config).ok()?;
            Some(drive(o, trial, budget, seed))
        }
        "cem" => {
            // The sweep's DiagonalCem: CMA-ES weights, 10 samples per update, the best 5
            // weighted, σ₀ = the step, σ at most twice the largest step, floor 10⁻⁶.
            let largest = steps.max();
            let config = CemConfig {
                weighting: Weighting::CmaEs,
                exploration_floor: 1e-6,
                max_variance: (2.0 * largest) * (2.0 * largest),
                max_evaluations: budget,
                ..CemConfig::DEFAULT
            };
            let o = DiagonalCem::<N, 10, 5>::try_with_variances(
                bounds,
                start,
                steps.component_mul(&steps),
                config,
            )
            .ok()?;
            Some(drive(o, trial, budget, seed))
        }
        "rockstar" => {
            let config = RockstarConfig {
                initial_sigma: fraction,
                max_evaluations: budget,
                ..RockstarConfig::DEFAULT
            };
            let o = Rockstar::<N, 160>::try_new(bounds, start, config).ok()?;
            Some(drive(o, trial, budget, seed))
        }
        "linebo" | "linebo-safe" => {
            let config = line_bo_config(trial, budget, method == "linebo-safe")?;
            let o = LineBo::<N, 64>::try_new(bounds, start, config).ok()?;
            Some(drive(o, trial, budget, seed))
        }
        _ => None,
    }
}

/// Asks and tells `optimizer` on `trial` for `budget` episodes (or until it stops).
fn drive<const N: usize, O: Optimizer<N>>(
    mut optimizer: O,
    trial: &mut Trial,
    budget: u32,
    seed: u64,
) -> RunReport {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut costs = Vec::with_capacity(budget as usize);
    let mut unsafe_episodes = 0;
    let mut spent = std::time::Duration::ZERO;
    while costs.len() < budget as usize && optimizer.status() == Status::Running {
        let t0 = Instant::now();
        let Ok(theta) = optimizer.ask(&mut rng) else {
            break;
        };
        spent += t0.elapsed();
        let scored = trial.episode(theta.as_slice()).unwrap_or(Scored {
            cost: f32::INFINITY,
            unsafe_episode: true,
        });
        let cost = scored.cost;
        unsafe_episodes += usize::from(scored.unsafe_episode);
        costs.push(cost);
        let t1 = Instant::now();
        let told = optimizer.tell(cost.min(f32::MAX));
        spent += t1.elapsed();
        if told.is_err() {
            break;
        }
    }
    let returned = optimizer
        .best()
        .map_or_else(|| trial.start().to_vec(), |b| to_vec(&b.theta));
    RunReport {
        optimizer_ns: spent.as_nanos() as f64 / costs.len().max(1) as f64,
        costs,
        returned,
        unsafe_episodes,
        fallback_episodes: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle's safety judgement on the AUV (by cost) and the hopper (by the gait): the
    /// bound is the bare controller's cost plus the margin, the bare controller's own first
    /// episode is safe and has that cost, and the box's upper corner is unsafe on both (on
    /// the AUV a cost above the bound, on the hopper an episode off the gait).
    #[test]
    fn the_bare_controller_is_safe_and_the_box_corner_is_not() {
        for task in [Task::Auv, Task::Hopper] {
            let mut trial = Trial::new(task, 1);
            let bare = trial.start_cost().unwrap();
            assert_eq!(
                trial.safe_threshold(),
                Some(bare + SAFETY_MARGIN * bare.abs())
            );
            let start = trial.start().to_vec();
            let first = trial.episode(&start).unwrap();
            assert_eq!(first.cost, bare, "{task:?}");
            assert!(!first.unsafe_episode, "{task:?}");
            let corner = trial.upper().to_vec();
            assert!(trial.episode(&corner).unwrap().unsafe_episode, "{task:?}");
            // The bound's own episode is not counted as the trial's.
            assert_eq!(trial.evaluations(), 2);
        }
    }

    /// A warm-up episode shifts the disturbances by one episode: the warmed-up trial's bare
    /// cost is the nominal trial's second episode of the bare controller. The nominal
    /// conditions are `Trial::new`'s, and a turned current changes the cost.
    #[test]
    fn a_warm_up_episode_shifts_the_disturbances_by_one() {
        let mut nominal = Trial::new(Task::Auv, 3);
        let start = nominal.start().to_vec();
        let first = nominal.score(&start).unwrap();
        let second = nominal.score(&start).unwrap();
        let warm = Trial::with_conditions(Task::Auv, 3, Conditions::WARM_UP);
        assert_eq!(warm.start_cost(), Some(second));
        assert_ne!(first, second);
        let same = Trial::with_conditions(Task::Auv, 3, Conditions::parse("nominal").unwrap());
        assert_eq!(same.start_cost(), Some(first));
        let turned = Trial::with_conditions(Task::Auv, 3, Conditions::parse("rotated:30").unwrap());
        assert_ne!(turned.start_cost(), Some(first));
        assert_eq!(Conditions::parse("rotated:30"), Some(Conditions::ROTATED));
        assert_eq!(Conditions::parse("warm-up:1"), Some(Conditions::WARM_UP));
        assert_eq!(Conditions::parse("rotated:x"), None);
    }
}
