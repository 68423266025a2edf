//! The common adapter in a few lines: your nominal law made adaptive by a state-linear
//! correction ([`Corrected`]), tuned by coordinate search, scored by a quadratic cost.
//!
//! Every default is a documented knob, and the pieces stay reachable: [`AdapterBuilder::bounds`]
//! and [`AdapterBuilder::controller`] give the box and the controller to build another
//! optimizer or shaper around, and [`AdapterBuilder::build_with`] takes them.

use super::{Adapter, AdapterConfig, Corrected, Nominal};
use crate::bounds::Bounds;
use crate::cost::{QuadraticCost, Shaper};
use crate::error::Error;
use crate::optimizer::{CoordinateConfig, CoordinateSearch, Optimizer};
use crate::vector::Vector;

/// The adapter [`AdapterBuilder::build`] returns, to name it in a struct or a `static`:
/// coordinate search over P = A·S weights, your law `N` corrected, a quadratic cost over
/// an observation of A values (the errors).
pub type CorrectedAdapter<N, const A: usize, const S: usize, const P: usize> =
    Adapter<CoordinateSearch<P>, Corrected<N, A, S, P>, QuadraticCost<A>, P, S, A>;

/// Builds the common adapter: A actions, S state values, P = A·S parameters (checked at
/// compile time).
///
/// | knob | default | meaning |
/// | --- | --- | --- |
/// | `dt` (in [`new`](Self::new)) | — | the control period, s |
/// | `limit` (in `new`) | — | the largest correction per axis, in action units |
/// | `scale` (in `new`) | — | per state value: the size at which it alone may command the whole correction |
/// | [`learning_episodes`](Self::learning_episodes) | 50 | then the best θ is deployed |
/// | [`failure_cost`](Self::failure_cost) | 10⁶ | told for a failed episode; keep it above any real cost |
/// | [`max_faulty_ticks`](Self::max_faulty_ticks) | 0 | non-finite ticks an episode may have and still count |
/// | [`output_limit`](Self::output_limit) | none | \|u_i\| of the corrected action (your actuator's range) |
/// | [`cost_weights`](Self::cost_weights) | 1 | the cost is ∫ Σ w_i e_i² dt over the observation e you pass to `control` |
/// | [`search`](Self::search) | step 0.1, tolerance 10⁻³ | coordinate search in the unit box of θ |
/// | [`initial`](Self::initial) | 0 (the bare law) | the θ the search starts from and deploys before any episode |
///
/// Why these: θ lives in the unit box (see [`Corrected`]), so one step suits every weight;
/// 0.1 is a twentieth of the box, small enough that the first candidates stay close to the
/// controller the robot already runs (the start θ = 0 is the bare law), and the
/// line search's expansions double it where the cost keeps falling.
///
/// ```
/// use ctrl_adapt::controller::AdapterBuilder;
/// use ctrl_adapt::Vector;
/// use rand_xoshiro::Xoshiro128PlusPlus;
///
/// // Your PD, unchanged: it keeps its previous error.
/// let mut previous = 0.0;
/// let pd = move |s: &Vector<2>, _t: f32| {
///     let u = 4.0 * s[0] + 3.6 * (s[0] - previous) / 0.02;
///     previous = s[0];
///     Vector::from([u])
/// };
/// // Correction up to ±3, full at 0.1 of error or of velocity.
/// let mut adapter = AdapterBuilder::<1, 2, 2>::new(0.02, [3.0], [0.1, 0.1])
///     .learning_episodes(40)
///     .build(pd)?;
/// let theta = adapter.begin_seeded_episode::<Xoshiro128PlusPlus>(7)?;
/// let state = Vector::from([1.0, 0.0]);
/// let u = adapter.control(&state, &Vector::from([state[0]])); // error as the observation
/// assert!(u[0].is_finite());
/// adapter.end_episode()?;
/// assert_eq!(theta, Vector::<2>::zeros()); // the first episode runs the bare PD
/// # Ok::<(), Box<dyn core::error::Error>>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdapterBuilder<const A: usize, const S: usize, const P: usize> {
    limit: Vector<A>,
    scale: Vector<S>,
    output_limit: Vector<A>,
    cost_weights: Vector<A>,
    search: CoordinateConfig,
    initial: Vector<P>,
    config: AdapterConfig,
}

impl<const A: usize, const S: usize, const P: usize> AdapterBuilder<A, S, P> {
    /// The defaults of the table above, for control period `dt` (s), correction limit
    /// `limit` per axis and state `scale`; nothing is checked until a `build`.
    pub fn new(dt: f32, limit: impl Into<Vector<A>>, scale: impl Into<Vector<S>>) -> Self {
        const { assert!(P == A * S, "θ holds the A·S weights: P = A·S") };
        Self {
            limit: limit.into(),
            scale: scale.into(),
            output_limit: Vector::repeat(f32::INFINITY),
            cost_weights: Vector::repeat(1.0),
            search: CoordinateConfig {
                initial_step: 0.1,
                tolerance: 1e-3,
                ..CoordinateConfig::DEFAULT
            },
            initial: Vector::zeros(),
            config: AdapterConfig {
                dt,
                failure_cost: 1e6,
                max_faulty_ticks: 0,
                learning_episodes: 50,
            },
        }
    }

    /// Learning episodes before the best θ is deployed.
    pub fn learning_episodes(mut self, episodes: u32) -> Self {
        self.config.learning_episodes = episodes;
        self
    }

    /// The cost told for a failed episode (finite; above any real episode's cost).
    pub fn failure_cost(mut self, cost: f32) -> Self {
        self.config.failure_cost = cost;
        self
    }

    /// Non-finite ticks an episode may have before it fails.
    pub fn max_faulty_ticks(mut self, ticks: u32) -> Self {
        self.config.max_faulty_ticks = ticks;
        self
    }

    /// The limit of the corrected action per axis (> 0).
    pub fn output_limit(mut self, limit: impl Into<Vector<A>>) -> Self {
        self.output_limit = limit.into();
        self
    }

    /// The weights of the quadratic cost (finite, ≥ 0).
    pub fn cost_weights(mut self, weights: impl Into<Vector<A>>) -> Self {
        self.cost_weights = weights.into();
        self
    }

    /// The coordinate search's parameters, in the unit box of θ.
    pub fn search(mut self, config: CoordinateConfig) -> Self {
        self.search = config;
        self
    }

    /// The θ to start from (inside the unit box): a correction learned elsewhere.
    pub fn initial(mut self, theta: Vector<P>) -> Self {
        self.initial = theta;
        self
    }

    /// The box of θ: [−1, 1]^P (see [`Corrected`]).
    pub fn bounds(&self) -> Bounds<P> {
        Bounds::unit()
    }

    /// The adapter's configuration (period, failure cost, faulty ticks, episodes).
    pub fn config(&self) -> AdapterConfig {
        self.config
    }

    /// The controller alone: `nominal` corrected within the limit, scale and output limit.
    pub fn controller<N: Nominal<S, A>>(&self, nominal: N) -> Result<Corrected<N, A, S, P>, Error> {
        Corrected::try_new(nominal, self.limit, self.scale)?.with_output_limit(self.output_limit)
    }

    /// The adapter: coordinate search from [`initial`](Self::initial), your `nominal` law
    /// corrected, the quadratic cost. Errors name the first invalid knob.
    pub fn build<N: Nominal<S, A>>(
        self,
        nominal: N,
    ) -> Result<CorrectedAdapter<N, A, S, P>, Error> {
        self.bounds().check(&self.initial, "initial")?;
        let search = CoordinateSearch::try_new(self.bounds(), self.initial, self.search)?;
        let shaper = QuadraticCost::try_new(self.cost_weights)?;
        self.build_with(search, shaper, nominal)
    }

    /// The adapter with an optimizer and a shaper of your choice (over [`bounds`](Self::bounds)).
    pub fn build_with<O, Sh, N>(
        self,
        optimizer: O,
        shaper: Sh,
        nominal: N,
    ) -> Result<Adapter<O, Corrected<N, A, S, P>, Sh, P, S, A>, Error>
    where
        O: Optimizer<P>,
        Sh: Shaper,
        N: Nominal<S, A>,
    {
        let controller = self.controller(nominal)?;
        Adapter::try_new(optimizer, controller, shaper, self.config, self.initial)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::{Controller, Mode};
    use crate::optimizer::Sracos;
    use rand_xoshiro::Xoshiro128PlusPlus;

    fn pd(s: &Vector<2>, _t: f32) -> Vector<1> {
        Vector::from([4.0 * s[0] - 3.6 * s[1]])
    }

    #[test]
    fn every_knob_is_checked_at_build() {
        let b = AdapterBuilder::<1, 2, 2>::new(0.02, [3.0], [0.1, 0.1]);
        let err = |b: AdapterBuilder<1, 2, 2>| b.build(pd).err();
        let invalid = Error::InvalidParameter;
        assert_eq!(err(b), None);
        let cases = [
            (AdapterBuilder::new(0.0, [3.0], [0.1, 0.1]), invalid("dt")),
            (
                AdapterBuilder::new(0.02, [-3.0], [0.1, 0.1]),
                invalid("limit"),
            ),
            (
                AdapterBuilder::new(0.02, [3.0], [0.1, 0.0]),
                invalid("scale"),
            ),
            (b.failure_cost(f32::INFINITY), invalid("failure_cost")),
            (b.output_limit([0.0]), invalid("output_limit")),
            (b.cost_weights([f32::NAN]), invalid("weights")),
            (
                b.initial(Vector::from([2.0, 0.0])),
                Error::OutOfBounds("initial"),
            ),
            (
                b.search(CoordinateConfig {
                    initial_step: -1.0,
                    ..CoordinateConfig::DEFAULT
                }),
                invalid("initial_step"),
            ),
        ];
        for (builder, expected) in cases {
            assert_eq!(err(builder), Some(expected));
        }
    }

    /// Checks: the built adapter runs the bare law on its first episode (θ = 0), applies the
    /// output limit, and `build_with` takes another optimizer over the same box.
    #[test]
    fn the_built_adapter_starts_from_the_bare_law() {
        let mut a = AdapterBuilder::<1, 2, 2>::new(0.02, [3.0], [0.1, 0.1])
            .output_limit([2.0])
            .build(pd)
            .unwrap();
        assert_eq!(
            a.begin_seeded_episode::<Xoshiro128PlusPlus>(1),
            Ok(Vector::zeros())
        );
        let s = Vector::from([0.3, 0.0]);
        // θ = 0: nominal 1.2, inside the output limit.
        assert_eq!(a.control(&s, &Vector::from([0.3])), Vector::from([1.2]));
        let report = a.end_episode().unwrap();
        assert_eq!(report.mode, Mode::Learn);
        let b = AdapterBuilder::<1, 2, 2>::new(0.02, [3.0], [0.1, 0.1]).output_limit([2.0]);
        let mut c = b.controller(pd).unwrap();
        let u = c.corrected(&Vector::from([1.0, 0.0]), &s, 0.0);
        assert_eq!(u, Vector::from([2.0]), "1.2 + 3 limited to 2");
        let sracos =
            Sracos::<2>::try_new(b.bounds(), crate::optimizer::SracosConfig::DEFAULT).unwrap();
        let cost = QuadraticCost::try_new(Vector::<1>::repeat(1.0)).unwrap();
        assert!(b.build_with(sracos, cost, pd).is_ok());
    }
}
