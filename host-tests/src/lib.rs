//! Host (std) harness for `ctrl-adapt`: objective functions and a driver that runs any
//! [`Optimizer`] against them, shared by the integration tests, the demo and the benchmarks.
//! The plants: [`auv`] (survey under a current) and [`hopper`] (hopping leg); the experiment
//! tasks that drive them through the library's adapter: [`auv_task`] and [`hopper_task`];
//! the demo's figures: [`plots`]; the test NOR flash of the checkpoint tests: [`cut_flash`].

use ctrl_adapt::controller::{Adapter, AdapterError, Controller, EpisodeReport, EpisodeRunner};
use ctrl_adapt::cost::Shaper;
use ctrl_adapt::optimizer::{Error, Optimizer, Status, Vector};
use rand_core::RngCore;

pub mod adversarial;
pub mod arm;
pub mod auv;
pub mod auv_task;
pub mod cut_flash;
pub mod double_integrator;
pub mod forgery;
pub mod functions;
pub mod guide;
pub mod hopper;
pub mod hopper_task;
pub mod hopper_tuning;
pub mod pil;
pub mod pil_flash;
pub mod plots;
pub mod reaching;
pub mod rhythmic;

/// What one optimisation run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct Run<const N: usize> {
    /// Cost of every evaluation, in order.
    pub costs: Vec<f32>,
    /// Best cost after each evaluation (non-increasing).
    pub best_costs: Vec<f32>,
    /// The best parameters found.
    pub best_theta: Vector<N>,
    /// Status when the run ended.
    pub status: Status,
}

impl<const N: usize> Run<N> {
    /// The best cost found.
    pub fn best_cost(&self) -> f32 {
        self.best_costs.last().copied().unwrap_or(f32::INFINITY)
    }
}

/// Runs `optimizer` on `objective` until it stops or `max_evaluations` costs are told,
/// calling `on_eval(evaluation, cost, best)` after each one (for progress displays).
pub fn run<const N: usize, O, R>(
    optimizer: &mut O,
    rng: &mut R,
    max_evaluations: usize,
    mut objective: impl FnMut(&Vector<N>, &mut R) -> f32,
    mut on_eval: impl FnMut(usize, f32, f32),
) -> Result<Run<N>, Error>
where
    O: Optimizer<N>,
    R: RngCore,
{
    let mut costs = Vec::new();
    let mut best_costs = Vec::new();
    while optimizer.status() == Status::Running && costs.len() < max_evaluations {
        let theta = optimizer.ask(rng)?;
        let cost = objective(&theta, rng);
        optimizer.tell(cost)?;
        let best = optimizer.best().map_or(cost, |b| b.cost);
        costs.push(cost);
        best_costs.push(best);
        on_eval(costs.len(), cost, best);
    }
    let best_theta = optimizer.best().map_or_else(Vector::zeros, |b| b.theta);
    Ok(Run {
        costs,
        best_costs,
        best_theta,
        status: optimizer.status(),
    })
}

/// What an episode driver needs of the library once an episode has begun: the tick-level
/// calls that [`Adapter`] (learning, deploying) and [`EpisodeRunner`] (a fixed θ, no
/// optimizer) share, so one driver per plant serves both.
pub trait Episodic<Sh: Shaper, const P: usize, const S: usize, const A: usize> {
    /// One control tick ([`Adapter::control`]).
    fn control(&mut self, state: &Vector<S>, observation: &Sh::Observation) -> Vector<A>;
    /// The cost shaper's running figures.
    fn shaper(&self) -> &Sh;
    /// Ends the episode ([`Adapter::end_episode`]).
    fn end_episode(&mut self) -> Result<EpisodeReport<P>, AdapterError>;
    /// Ends the episode as failed ([`Adapter::abort_episode`]).
    fn abort_episode(&mut self) -> Result<EpisodeReport<P>, AdapterError>;
}

macro_rules! episodic {
    ($ty:ty, $($bounds:tt)*) => {
        impl<$($bounds)*, const P: usize, const S: usize, const A: usize> Episodic<Sh, P, S, A>
            for $ty
        {
            fn control(&mut self, state: &Vector<S>, observation: &Sh::Observation) -> Vector<A> {
                <$ty>::control(self, state, observation)
            }
            fn shaper(&self) -> &Sh {
                <$ty>::shaper(self)
            }
            fn end_episode(&mut self) -> Result<EpisodeReport<P>, AdapterError> {
                <$ty>::end_episode(self)
            }
            fn abort_episode(&mut self) -> Result<EpisodeReport<P>, AdapterError> {
                <$ty>::abort_episode(self)
            }
        }
    };
}

episodic!(
    Adapter<O, C, Sh, P, S, A, G>,
    O: Optimizer<P>,
    C: Controller<P, S, A>,
    Sh: Shaper,
    G: ctrl_adapt::controller::guard::Supervisor<S>
);
episodic!(EpisodeRunner<C, Sh, P, S, A>, C: Controller<P, S, A>, Sh: Shaper);

/// Uniform random search, the baseline of the classification-based optimizers: the best
/// cost of `budget` uniform samples of `bounds`.
pub fn random_search<const N: usize, R: RngCore>(
    bounds: &ctrl_adapt::optimizer::Bounds<N>,
    budget: usize,
    rng: &mut R,
    mut objective: impl FnMut(&Vector<N>) -> f32,
) -> f32 {
    (0..budget)
        .map(|_| objective(&bounds.sample_uniform(rng)))
        .fold(f32::INFINITY, f32::min)
}

/// The median of `v` (the mean of the two middle values for an even count; NaN when empty).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Spearman's rank correlation of `a` and `b`: ranks with ties averaged, then Pearson's
/// correlation of the ranks (0 if either is constant).
pub fn spearman(a: &[f32], b: &[f32]) -> f64 {
    fn ranks(v: &[f32]) -> Vec<f64> {
        let mut order: Vec<usize> = (0..v.len()).collect();
        order.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
        let mut r = vec![0.0; v.len()];
        let mut i = 0;
        while i < order.len() {
            let mut j = i;
            while j + 1 < order.len() && v[order[j + 1]] == v[order[i]] {
                j += 1;
            }
            for k in i..=j {
                r[order[k]] = (i + j) as f64 / 2.0;
            }
            i = j + 1;
        }
        r
    }
    let (ra, rb) = (ranks(a), ranks(b));
    let n = a.len() as f64;
    let (ma, mb) = (ra.iter().sum::<f64>() / n, rb.iter().sum::<f64>() / n);
    let cov: f64 = ra.iter().zip(&rb).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = ra.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = rb.iter().map(|y| (y - mb).powi(2)).sum();
    if va == 0.0 || vb == 0.0 {
        0.0
    } else {
        cov / (va * vb).sqrt()
    }
}
