//! The book-keeping every optimizer shares: the pending candidate, the evaluation count
//! against the budget, the status and the best (θ, cost) so far, with the ask prologue and
//! the tell epilogue written once.

use super::{Best, Status};
use crate::bounds::Bounds;
use crate::error::Error;
use crate::vector::Vector;

/// The five [`Optimizer`](super::Optimizer) accessors every algorithm answers the same way,
/// from its `ledger` and `bounds` fields; used inside each `impl Optimizer<N> for …` block.
macro_rules! ledger_accessors {
    () => {
        $crate::optimizer::ledger_accessors!(bounds);
    };
    ($($bounds:ident).+) => {
        fn best(&self) -> Option<$crate::optimizer::Best<N>> {
            self.ledger.best()
        }

        fn pending(&self) -> Option<&$crate::optimizer::Vector<N>> {
            self.ledger.pending()
        }

        fn evaluations(&self) -> u32 {
            self.ledger.evaluations()
        }

        fn status(&self) -> $crate::optimizer::Status {
            self.ledger.status()
        }

        fn bounds(&self) -> &$crate::optimizer::Bounds<N> {
            &self.$($bounds).+
        }
    };
}
pub(crate) use ledger_accessors;

/// The book-keeping every algorithm shares: the pending candidate, the evaluation count
/// against the budget, the status, and the best (θ, cost) so far. Keeping it in one place makes the
/// "rejected call changes nothing" rule hold the same way in every optimizer.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub(crate) struct Ledger<const N: usize> {
    pending: Option<Vector<N>>,
    evaluations: u32,
    budget: u32,
    status: Status,
    best: Option<Best<N>>,
}

impl<const N: usize> Ledger<N> {
    /// A fresh ledger allowing `budget` evaluations.
    /// Every optimizer's constructor makes one, so this is where a dimension of zero is
    /// refused at compile time (a box of [`Bounds::try_new`](crate::Bounds::try_new) already
    /// cannot have one; this also covers a box read from a record).
    pub(crate) const fn new(budget: u32) -> Self {
        const { assert!(N > 0, "an optimizer needs at least one parameter") };
        Self {
            pending: None,
            evaluations: 0,
            budget,
            status: Status::Running,
            best: None,
        }
    }

    /// The ask prologue: `Some` pending candidate to hand out again (ask is idempotent),
    /// [`Error::Stopped`] once the search has stopped, `None` when a new candidate is due.
    pub(crate) fn reissue(&self) -> Result<Option<Vector<N>>, Error> {
        match self.pending {
            Some(pending) => Ok(Some(pending)),
            None if self.status != Status::Running => Err(Error::Stopped),
            None => Ok(None),
        }
    }

    /// The tell epilogue: a running search that has used its budget stops.
    pub(crate) fn settle(&mut self) {
        if self.status == Status::Running && self.budget_spent() {
            self.status = Status::BudgetSpent;
        }
    }

    /// Where the search stands.
    pub(crate) fn status(&self) -> Status {
        self.status
    }

    /// Stops the search (`Converged` or `BudgetSpent`).
    pub(crate) fn stop(&mut self, status: Status) {
        self.status = status;
    }

    /// Hands out `theta` (see [`Ledger::hand_out`]), or, when the search has no candidate
    /// left to propose (`None`), stops it as converged and answers [`Error::Stopped`].
    pub(crate) fn hand_out_or_stop(
        &mut self,
        theta: Option<Vector<N>>,
        bounds: &Bounds<N>,
    ) -> Result<Vector<N>, Error> {
        match theta {
            Some(theta) => Ok(self.hand_out(theta, bounds)),
            None => {
                self.stop(Status::Converged);
                Err(Error::Stopped)
            }
        }
    }

    /// Marks `theta`, projected onto `bounds`, as handed out and returns it.
    ///
    /// Every algorithm already proposes inside the box, so the projection changes nothing
    /// there (N comparisons per ask). It is the backstop of the contract "`ask` returns a
    /// finite θ inside the box": whatever state an optimizer is in (a record forged past
    /// [`Persistent::validate`](crate::record::Persistent::validate), a defect), no θ outside
    /// the box and no NaN reaches the plant (a NaN coordinate becomes the lower bound). It
    /// projects rather than returns an error because an error would stop learning for good
    /// (a state that proposes NaN once proposes it again) while the projected θ is as safe
    /// as any candidate; and it lives here, in the one place every `ask` passes through.
    pub(crate) fn hand_out(&mut self, mut theta: Vector<N>, bounds: &Bounds<N>) -> Vector<N> {
        bounds.project(&mut theta);
        self.pending = Some(theta);
        theta
    }

    /// The checks of a decoded ledger against the box of its optimizer: a pending
    /// candidate and the best θ finite and inside the box, the best cost finite, a budget of
    /// at least one evaluation, and a running search that has not used it up.
    #[cfg(feature = "serde")]
    pub(crate) fn check_decoded(&self, bounds: &Bounds<N>) -> Result<(), Error> {
        if let Some(pending) = &self.pending {
            bounds.check(pending, "pending")?;
        }
        if let Some(best) = &self.best {
            bounds.check(&best.theta, "best")?;
            crate::error::require_finite([&best.cost], "best")?;
        }
        crate::error::require(self.budget != 0, "max_evaluations")?;
        crate::error::require(
            self.status != Status::Running || self.evaluations < self.budget,
            "evaluations",
        )?;
        crate::error::require(self.best.is_some() == (self.evaluations > 0), "evaluations")
    }

    /// Checks a `tell` before anything is changed; on success takes the pending candidate,
    /// counts the evaluation and updates the best, returning the candidate.
    pub(crate) fn accept(&mut self, cost: f32) -> Result<Vector<N>, Error> {
        let theta = self.pending.ok_or(Error::NoPendingAsk)?;
        if !cost.is_finite() {
            return Err(Error::NonFinite("cost"));
        }
        self.pending = None;
        self.evaluations = self.evaluations.saturating_add(1);
        if self.best.is_none_or(|b| cost < b.cost) {
            self.best = Some(Best { theta, cost });
        }
        Ok(theta)
    }

    pub(crate) fn pending(&self) -> Option<&Vector<N>> {
        self.pending.as_ref()
    }

    pub(crate) fn evaluations(&self) -> u32 {
        self.evaluations
    }

    /// How many candidates can be in flight ([`Generation::room`](super::Generation)) when
    /// the algorithm can draw the next `rest` without their costs: `rest` within the
    /// evaluations left in the budget, 0 once the search has stopped.
    pub(crate) fn room(&self, rest: usize) -> usize {
        if self.status != Status::Running {
            return 0;
        }
        rest.min(self.budget.saturating_sub(self.evaluations) as usize)
    }

    pub(crate) fn budget_spent(&self) -> bool {
        self.evaluations >= self.budget
    }

    pub(crate) fn best(&self) -> Option<Best<N>> {
        self.best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ledger_rejects_without_change() {
        let mut l = Ledger::<2>::new(3);
        assert_eq!(l.accept(1.0), Err(Error::NoPendingAsk));
        l.hand_out(
            Vector::from([0.5, 0.5]),
            &Bounds::uniform(0.0, 1.0).unwrap(),
        );
        let before = l;
        assert_eq!(l.accept(f32::NAN), Err(Error::NonFinite("cost")));
        assert_eq!(l.accept(f32::NEG_INFINITY), Err(Error::NonFinite("cost")));
        assert_eq!(l, before);
        assert!(l.accept(2.0).is_ok());
        assert_eq!(l.evaluations(), 1);
        assert_eq!(l.best().map(|b| b.cost), Some(2.0));
    }

    /// Checks the backstop of `ask`: whatever an algorithm proposes, the candidate handed
    /// out (and kept pending) is finite and inside the box: NaN maps to the lower bound, ±∞
    /// and values outside to the nearest face, a point inside is unchanged.
    #[test]
    fn handed_out_candidates_are_projected_onto_the_box() {
        let bounds = Bounds::try_new([-1.0, 0.0].into(), [1.0, 2.0].into()).unwrap();
        let mut l = Ledger::<2>::new(10);
        for (proposed, handed) in [
            ([f32::NAN, 0.5], [-1.0, 0.5]),
            ([f32::INFINITY, f32::NEG_INFINITY], [1.0, 0.0]),
            ([-3.0, 2.5], [-1.0, 2.0]),
            ([0.25, 1.75], [0.25, 1.75]),
        ] {
            let theta = l.hand_out(proposed.into(), &bounds);
            assert_eq!(theta, Vector::from(handed));
            assert_eq!(l.pending(), Some(&theta));
            l.accept(1.0).unwrap();
        }
    }
}
