//! The two-phase strategy of Leonetti et al. 2012 (sections 4 and 5): a global search
//! (controlled random search, or SRACOS) run off-line, in simulation, whose best θ
//! warm-starts the local [`CoordinateSearch`] run on-line, on the robot.
//!
//! [`TwoPhase`] chains the two behind the one ask/tell interface: it hands out the global
//! optimizer's candidates until that stops (or its budget is spent), then starts the
//! coordinate search *at the global best θ*, whose first candidate is that θ itself, so the
//! hand-over keeps the best θ and measures it again in the new conditions.
//!
//! The phases need not run on the same machine: a firmware that only runs the second phase
//! builds its [`CoordinateSearch`] from a θ computed on a host (stored in flash, sent over a
//! link), exactly as [`TwoPhase`] does at the hand-over:
//!
//! ```
//! use ctrl_adapt::optimizer::{Bounds, CoordinateConfig, CoordinateSearch, Optimizer};
//! use rand_core::SeedableRng;
//! let theta_from_host = [0.12, -0.4, 0.05].into(); // e.g. the host's CRS best
//! let bounds = Bounds::<3>::uniform(-1.0, 1.0)?;
//! let mut local = CoordinateSearch::try_new(bounds, theta_from_host, CoordinateConfig::DEFAULT)?;
//! let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(7);
//! assert_eq!(local.ask(&mut rng)?, theta_from_host); // phase 2 starts by re-measuring it
//! # Ok::<(), ctrl_adapt::optimizer::Error>(())
//! ```

use rand_core::RngCore;

use super::{
    Best, Bounds, CoordinateConfig, CoordinateSearch, Draw, Error, Generation, Optimizer, Status,
    Vector,
};
use crate::error::require;

/// Which phase a [`TwoPhase`] is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Phase {
    /// The global search is running.
    Global,
    /// The local coordinate search is running from the global best.
    Local,
}

/// A global optimizer `G` for at most `global_budget` evaluations, then a
/// [`CoordinateSearch`] from its best θ.
///
/// Under [`InFlight`](super::InFlight), the global phase's generation goes out together (a
/// controlled random search's initial set) but never past the global budget, so the
/// hand-over happens with nothing in flight; the local phase takes one at a time.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TwoPhase<G, const N: usize> {
    global: G,
    global_budget: u32,
    local_config: CoordinateConfig,
    local_steps: Vector<N>,
    local: Option<CoordinateSearch<N>>,
}

impl<G: Optimizer<N>, const N: usize> TwoPhase<G, N> {
    /// Runs `global` for at most `global_budget` (≥ 1) evaluations, then a coordinate search
    /// configured by `local_config`.
    pub fn try_new(
        global: G,
        global_budget: u32,
        local_config: CoordinateConfig,
    ) -> Result<Self, Error> {
        Self::try_with_steps(
            global,
            global_budget,
            Vector::repeat(local_config.initial_step),
            local_config,
        )
    }

    /// As [`TwoPhase::try_new`] with per-coordinate initial steps for the local phase.
    pub fn try_with_steps(
        global: G,
        global_budget: u32,
        local_steps: Vector<N>,
        local_config: CoordinateConfig,
    ) -> Result<Self, Error> {
        check_phases(global_budget, &local_steps, &local_config)?;
        Ok(Self {
            global,
            global_budget,
            local_config,
            local_steps,
            local: None,
        })
    }

    /// The current phase.
    pub fn phase(&self) -> Phase {
        if self.local.is_some() {
            Phase::Local
        } else {
            Phase::Global
        }
    }

    /// The global optimizer (its best is the hand-over point).
    pub fn global(&self) -> &G {
        &self.global
    }

    /// The local search, once started.
    pub fn local(&self) -> Option<&CoordinateSearch<N>> {
        self.local.as_ref()
    }

    /// Starts the local phase now from the global best (on demand, e.g. when the simulator
    /// result is good enough). Errors while a global candidate is pending, or before the
    /// global phase has told anything.
    pub fn hand_over(&mut self) -> Result<(), Error> {
        if self.local.is_some() {
            return Ok(());
        }
        if self.global.pending().is_some() {
            return Err(Error::CandidatePending);
        }
        let best = self.global.best().ok_or(Error::NoEvaluation)?;
        self.local = Some(CoordinateSearch::try_with_steps(
            *self.global.bounds(),
            best.theta,
            self.local_steps,
            self.local_config,
        )?);
        Ok(())
    }

    fn global_done(&self) -> bool {
        self.global.status() != Status::Running || self.global.evaluations() >= self.global_budget
    }
}

/// The checks of [`TwoPhase::try_with_steps`]: a global budget ≥ 1, a valid local
/// configuration, finite positive local steps.
fn check_phases<const N: usize>(
    global_budget: u32,
    local_steps: &Vector<N>,
    local_config: &CoordinateConfig,
) -> Result<(), Error> {
    require(global_budget != 0, "global_budget")?;
    local_config.validate()?;
    require(
        local_steps.iter().all(|s| s.is_finite() && *s > 0.0),
        "initial_step",
    )
}

#[cfg(feature = "serde")]
impl<G: Optimizer<N> + crate::record::Persistent, const N: usize> TwoPhase<G, N> {
    /// The checks of a decoded search ([`Persistent::validate`](crate::record::Persistent)):
    /// the constructor's (a global budget ≥ 1, the local configuration and steps), the
    /// global optimizer's own, and the local search's own, over the global optimizer's box.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        check_phases(self.global_budget, &self.local_steps, &self.local_config)?;
        self.global.validate()?;
        if let Some(local) = &self.local {
            local.check_decoded()?;
            require(local.bounds() == self.global.bounds(), "local")?;
        }
        Ok(())
    }
}

impl<G: Optimizer<N>, const N: usize> Optimizer<N> for TwoPhase<G, N> {
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        match self.local.as_mut() {
            Some(local) => local.ask(rng),
            None => self.global.ask(rng),
        }
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        match self.local.as_mut() {
            Some(local) => local.tell(cost),
            None => {
                self.global.tell(cost)?;
                if self.global_done() {
                    // The global phase has told at least this cost, so it has a best.
                    self.hand_over()?;
                }
                Ok(())
            }
        }
    }

    /// Before the hand-over, the global phase's best. After it, the local phase's best: the
    /// phases score in different conditions (the global phase in a simulator, the local one
    /// on the robot), and costs measured in different conditions are not comparable, so a
    /// simulator cost never outranks a robot measurement. After the hand-over and before the
    /// local phase has told anything, the hand-over point (the global best, with its global
    /// cost: nothing else is known yet), which is also the local phase's first candidate.
    ///
    /// So `best` may get worse at the hand-over (the robot re-measures the global best, in
    /// new conditions); an [`Adapter`](crate::controller::Adapter) around a `TwoPhase`
    /// deploys a θ measured on the robot. The global phase's best stays readable through
    /// [`TwoPhase::global`].
    fn best(&self) -> Option<Best<N>> {
        match self.local.as_ref() {
            Some(local) => local.best().or_else(|| self.global.best()),
            None => self.global.best(),
        }
    }

    fn pending(&self) -> Option<&Vector<N>> {
        match self.local.as_ref() {
            Some(local) => local.pending(),
            None => self.global.pending(),
        }
    }

    fn evaluations(&self) -> u32 {
        let local = self.local.as_ref().map_or(0, |l| l.evaluations());
        self.global.evaluations().saturating_add(local)
    }

    fn status(&self) -> Status {
        self.local.as_ref().map_or(Status::Running, |l| l.status())
    }

    fn bounds(&self) -> &Bounds<N> {
        self.global.bounds()
    }
}

/// While the global phase runs, its room (within the evaluations left of the global budget,
/// so that no candidate of the global phase is out at the hand-over); after it, the local
/// coordinate search's (one at a time).
impl<G: Generation<N>, const N: usize> Generation<N> for TwoPhase<G, N> {
    fn room(&self) -> usize {
        match &self.local {
            Some(local) => local.room(),
            None => {
                let left = self.global_budget.saturating_sub(self.global.evaluations());
                self.global
                    .room()
                    .min(usize::try_from(left).unwrap_or(usize::MAX))
            }
        }
    }

    fn most(&self) -> usize {
        let global = self
            .global
            .most()
            .min(usize::try_from(self.global_budget).unwrap_or(usize::MAX));
        global.max(1)
    }

    fn draws_ahead(&self) -> bool {
        self.local.is_none() && self.global.draws_ahead()
    }

    fn adopts_pending(&self) -> bool {
        match &self.local {
            Some(local) => local.adopts_pending(),
            None => self.global.adopts_pending(),
        }
    }

    fn draw<R: RngCore + ?Sized>(&mut self, ahead: usize, rng: &mut R) -> Result<Draw<N>, Error> {
        match self.local.as_mut() {
            Some(local) => local.draw(ahead, rng),
            None => self.global.draw(ahead, rng),
        }
    }

    fn resume(&mut self, draw: &Draw<N>) {
        match self.local.as_mut() {
            Some(local) => local.resume(draw),
            None => self.global.resume(draw),
        }
    }

    fn check_draw(&self, draw: &Draw<N>) -> Result<(), Error> {
        match &self.local {
            Some(local) => local.check_draw(draw),
            None => self.global.check_draw(draw),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimizer::{ControlledRandomSearch, CrsConfig};
    use rand_core::SeedableRng;
    use rand_xoshiro::Xoshiro128PlusPlus;

    /// Checks: after the hand-over `best` is the local phase's own best, even when the
    /// global phase's (simulator) cost is lower. The global phase's best θ is told 1.0; the
    /// local phase re-measures it first and is told 5.0 (other conditions), then worse
    /// costs: `best` is the local (θ, 5.0), and the global best stays readable.
    #[test]
    fn best_after_the_hand_over_is_the_local_phase_best() {
        let bounds = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let crs = ControlledRandomSearch::<2, 5>::try_new(bounds, CrsConfig::DEFAULT).unwrap();
        let mut two = TwoPhase::try_new(crs, 5, CoordinateConfig::DEFAULT).unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(3);
        let mut first = None;
        for k in 0..5 {
            let t = two.ask(&mut rng).unwrap();
            first.get_or_insert(t);
            two.tell(if k == 0 { 1.0 } else { 2.0 }).unwrap();
        }
        let global = Best {
            theta: first.unwrap(),
            cost: 1.0,
        };
        // Handed over, nothing measured locally yet: the hand-over point.
        assert_eq!(two.phase(), Phase::Local);
        assert_eq!(two.best(), Some(global));
        let handed = two.ask(&mut rng).unwrap();
        assert_eq!(handed, global.theta);
        two.tell(5.0).unwrap();
        let local = Best {
            theta: handed,
            cost: 5.0,
        };
        assert_eq!(two.best(), Some(local));
        for cost in [6.0, 7.0] {
            two.ask(&mut rng).unwrap();
            two.tell(cost).unwrap();
            assert_eq!(two.best(), Some(local));
        }
        assert_eq!(two.global().best(), Some(global));
        let t = two.ask(&mut rng).unwrap();
        two.tell(0.5).unwrap();
        assert_eq!(
            two.best(),
            Some(Best {
                theta: t,
                cost: 0.5
            })
        );
    }

    /// Checks: after the global budget the local phase starts, its first candidate is the
    /// global best θ, the best θ is kept until the local phase improves on it, and the
    /// local phase then refines a bimodal function to its global minimum.
    #[test]
    fn hand_over_keeps_the_best_theta() {
        // Two basins; the deeper one at (0.6, 0.6).
        let f = |t: &Vector<2>| {
            let a = (t - Vector::from([0.6, 0.6])).norm_squared();
            let b = (t - Vector::from([-0.5, -0.5])).norm_squared();
            (a * (b + 0.2)).min(10.0)
        };
        let bounds = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let crs = ControlledRandomSearch::<2, 20>::try_new(bounds, CrsConfig::DEFAULT).unwrap();
        let local = CoordinateConfig {
            initial_step: 0.05,
            tolerance: 1e-5,
            ..CoordinateConfig::DEFAULT
        };
        let mut two = TwoPhase::try_new(crs, 60, local).unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(11);
        for _ in 0..60 {
            assert_eq!(two.phase(), Phase::Global);
            let t = two.ask(&mut rng).unwrap();
            two.tell(f(&t)).unwrap();
        }
        assert_eq!(two.phase(), Phase::Local);
        let global_best = two.global().best().unwrap();
        assert_eq!(two.best(), Some(global_best));
        assert_eq!(two.ask(&mut rng).unwrap(), global_best.theta);
        two.tell(f(&global_best.theta)).unwrap();
        while let Ok(t) = two.ask(&mut rng) {
            two.tell(f(&t)).unwrap();
        }
        let best = two.best().unwrap();
        assert_eq!(two.status(), Status::Converged);
        assert!(best.cost <= global_best.cost);
        assert!(
            (best.theta - Vector::from([0.6, 0.6])).amax() < 1e-2,
            "{best:?}"
        );
    }

    /// Checks: under `InFlight` the global phase's initial set goes out together, capped by
    /// the global budget (3 of CRS's 5 points with a budget of 3, all 5 with 8); reported in
    /// reverse order, the state is the sequential run's; with the budget of 3 the hand-over
    /// has happened and the local phase takes one at a time.
    #[test]
    fn in_flight_hands_out_the_global_set_within_the_global_budget() {
        use crate::optimizer::InFlight;
        let bounds = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let crs = ControlledRandomSearch::<2, 5>::try_new(bounds, CrsConfig::DEFAULT).unwrap();
        for (budget, first) in [(3, 3), (8, 5)] {
            let two = TwoPhase::try_new(crs.clone(), budget, CoordinateConfig::DEFAULT).unwrap();
            let mut sequential = two.clone();
            let mut flight = InFlight::<_, 2, 8>::new(two);
            assert_eq!(flight.max_in_flight(), first);
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(5);
            let mut rng_sequential = rng.clone();
            let mut out = heapless::Vec::<_, 8>::new();
            while let Some(pair) = flight.suggest(&mut rng).unwrap() {
                out.push(pair).unwrap();
            }
            assert_eq!(out.len(), first);
            for (ticket, theta) in out.iter().rev() {
                flight.report(*ticket, theta.norm_squared()).unwrap();
            }
            for (_, theta) in &out {
                assert_eq!(sequential.ask(&mut rng_sequential), Ok(*theta));
                sequential.tell(theta.norm_squared()).unwrap();
            }
            assert_eq!(flight.optimizer(), &sequential);
            let local = if budget == 3 {
                Phase::Local
            } else {
                Phase::Global
            };
            assert_eq!(flight.optimizer().phase(), local);
            if budget == 3 {
                assert_eq!(flight.capacity(), 1);
            }
        }
    }

    #[test]
    fn hand_over_on_demand_waits_for_a_told_candidate() {
        let bounds = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let crs = ControlledRandomSearch::<2, 5>::try_new(bounds, CrsConfig::DEFAULT).unwrap();
        let mut two = TwoPhase::try_new(crs, 100, CoordinateConfig::DEFAULT).unwrap();
        assert_eq!(two.hand_over(), Err(Error::NoEvaluation));
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
        let t = two.ask(&mut rng).unwrap();
        assert_eq!(two.hand_over(), Err(Error::CandidatePending));
        two.tell(1.0).unwrap();
        two.hand_over().unwrap();
        assert_eq!(two.ask(&mut rng).unwrap(), t);
        assert_eq!(
            TwoPhase::try_new(two.global().clone(), 0, CoordinateConfig::DEFAULT).unwrap_err(),
            Error::InvalidParameter("global_budget")
        );
    }
}
