//! Several candidates in flight for host callers: [`InFlight`] hands out the candidates of
//! one generation with [`Ticket`]s, so that a simulator farm evaluates them in parallel,
//! and takes their costs back in any order.
//!
//! Firmware keeps the sequential contract of [`Optimizer`]: one candidate at a time, and
//! nothing here changes an optimizer's state, its record or its results. The host wraps an
//! optimizer into an `InFlight<O, N, C>` (at most `C` candidates out at once) and calls
//!
//! * [`InFlight::suggest`]: the next candidate and its ticket, or `None` while nothing more
//!   can be handed out before outstanding tickets are reported;
//! * [`InFlight::report`]: the cost of a ticket, in any order;
//! * [`InFlight::cancel`]: the episode failed; its candidate is handed out again (with a new
//!   ticket) by a later `suggest`;
//! * [`InFlight::capacity`]: how many more `suggest` calls return a candidate now.
//!
//! # How many at once
//! A candidate can be handed out before the costs of the earlier ones only where the
//! algorithm draws it without them ([`Generation::room`]):
//!
//! | optimizer | in flight at most |
//! | --- | --- |
//! | [`DiagonalCem`](super::DiagonalCem)`<N, K, E>` | K, the samples of an update |
//! | [`Cmaes`](super::Cmaes)`<N, L>` | λ = L, a generation |
//! | [`ControlledRandomSearch`](super::ControlledRandomSearch)`<N, M>` | M while it fills its set (Step 0), then 1 |
//! | [`Rockstar`](super::Rockstar) | `initial_samples`, then 1 |
//! | [`TwoPhase`](super::TwoPhase)`<G, N>` | G's while the global phase runs (within its budget), then 1 |
//! | [`CoordinateSearch`](super::CoordinateSearch), [`Sracos`](super::Sracos), [`Racos`](super::Racos), [`LineBo`](super::LineBo) | 1 |
//!
//! SRACOS is sequential by design (each candidate is drawn from the model the previous
//! cost updated). Batch RACOS keeps its model fixed during a batch but refuses a candidate
//! equal to one already told in that batch, so its candidates depend on the told costs'
//! order; it takes one at a time here. Always at most the evaluations left in the budget.
//!
//! # Bit for bit the sequential run
//! A generation's candidates are drawn in the order they are handed out, from the caller's
//! RNG, exactly as successive `ask`s draw them. A reported cost is held until every earlier
//! candidate of the generation has its cost, and then they are told to the optimizer in
//! hand-out order. So after a generation, in whatever order its costs came back, the
//! optimizer is in exactly the state (and the RNG at exactly the position) that the
//! sequential `ask`/`tell` with the same costs gives; until then [`Optimizer::best`] and
//! [`Optimizer::evaluations`] count only the costs already told. Holding the costs costs
//! `C` slots of 8N + 12 bytes in the wrapper, nothing in the optimizer.
//!
//! # Errors and mixing
//! A reported cost that is not finite ([`Error::NonFinite`]), a ticket not outstanding
//! ([`Error::UnknownTicket`]), a `suggest` on a stopped search ([`Error::Stopped`]) are
//! errors that change nothing. `InFlight` is an [`Optimizer`] too: its sequential `ask` and
//! `tell` work while nothing is in flight, and are [`Error::InFlight`] while tickets are
//! outstanding; `suggest` while a sequential `ask` is pending is
//! [`Error::CandidatePending`].
//!
//! # Records
//! With the `serde` feature an `InFlight` is persistent (tag `FLYT`): its record holds the
//! optimizer's and the slots of the generation (candidate, ticket or held cost), so a
//! restored one accepts the outstanding tickets. The optimizer alone
//! ([`InFlight::optimizer`]) saves the record the firmware loads.
//!
//! ```
//! use ctrl_adapt::optimizer::{CemConfig, DiagonalCem, InFlight};
//! use ctrl_adapt::Bounds;
//! use rand_core::SeedableRng;
//!
//! let bounds = Bounds::<3>::uniform(-1.0, 1.0)?;
//! let cem = DiagonalCem::<3, 6>::try_new(bounds, [0.5; 3].into(), CemConfig::DEFAULT)?;
//! let mut flight = InFlight::<_, 3, 6>::new(cem);
//! let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(1);
//! // One generation handed out at once ...
//! let mut out = Vec::new();
//! while let Some((ticket, theta)) = flight.suggest(&mut rng)? {
//!     out.push((ticket, theta.norm_squared()));
//! }
//! assert_eq!(out.len(), 6);
//! // ... and its costs reported in any order.
//! for &(ticket, cost) in out.iter().rev() {
//!     flight.report(ticket, cost)?;
//! }
//! assert_eq!(flight.optimizer().updates(), 1);
//! # Ok::<(), ctrl_adapt::Error>(())
//! ```

use heapless::Vec;
use rand_core::RngCore;

use super::{Best, Bounds, Error, Optimizer, Status, Vector};

/// The name of one candidate in flight, handed out by [`InFlight::suggest`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Ticket(u32);

impl Ticket {
    /// The ticket numbered `number` (as [`Ticket::get`] gave it, e.g. across a language line).
    pub const fn new(number: u32) -> Self {
        Self(number)
    }

    /// Its number.
    pub const fn get(self) -> u32 {
        self.0
    }
}

/// A candidate drawn ahead of the costs of the ones before it: θ as handed out, and what
/// the optimizer remembers of the draw for its `tell` (CMA-ES's standard normal z and the
/// excess of the unprojected point, ROCK*'s point in normalised coordinates). Made by
/// [`Generation::draw`], given back to [`Generation::resume`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Draw<const N: usize> {
    pub(crate) theta: Vector<N>,
    pub(crate) aux: Vector<N>,
    pub(crate) excess: f32,
}

impl<const N: usize> Draw<N> {
    /// A draw that is its candidate only.
    pub(crate) fn of(theta: Vector<N>) -> Self {
        Self {
            theta,
            aux: Vector::zeros(),
            excess: 0.0,
        }
    }

    /// The candidate.
    pub fn theta(&self) -> &Vector<N> {
        &self.theta
    }
}

/// What an optimizer tells [`InFlight`] about its generations; implemented by every
/// optimizer of the library and forwarded by [`AnyOptimizer`](super::AnyOptimizer).
///
/// The defaults describe a sequential optimizer: one candidate at a time, drawn by `ask`.
/// An optimizer that can draw ahead overrides all of the methods together.
pub trait Generation<const N: usize>: Optimizer<N> {
    /// How many candidates, counted from the next one the sequential `ask` would propose,
    /// can be drawn before any of them is told: the rest of the generation (within the
    /// budget), 1 for a sequential optimizer, 0 once it has stopped.
    fn room(&self) -> usize {
        usize::from(self.status() == Status::Running)
    }

    /// The most [`Generation::room`] can ever be for this optimizer and configuration.
    fn most(&self) -> usize {
        1
    }

    /// Whether [`Generation::draw`] leaves the optimizer without a pending candidate (it
    /// draws ahead) rather than going through `ask`.
    fn draws_ahead(&self) -> bool {
        false
    }

    /// Whether a candidate left pending by the sequential `ask` (or made pending by a
    /// constructor, such as a start) can go out under a ticket
    /// ([`InFlight::adopt_pending`]): its draw is the candidate alone. By default, when
    /// the optimizer does not draw ahead.
    fn adopts_pending(&self) -> bool {
        !self.draws_ahead()
    }

    /// The candidate `ahead` places after the next one the sequential `ask` would propose
    /// (`ahead` < [`Generation::room`]), drawn from `rng` exactly as that `ask` would draw
    /// it. A sequential optimizer asks (`ahead` is 0).
    fn draw<R: RngCore + ?Sized>(&mut self, ahead: usize, rng: &mut R) -> Result<Draw<N>, Error> {
        let _ = ahead;
        self.ask(rng).map(Draw::of)
    }

    /// Makes `draw` the pending candidate, as if the sequential `ask` had just proposed it,
    /// so that `tell` takes its cost. (After an `ask`-made draw it already is.)
    fn resume(&mut self, draw: &Draw<N>) {
        let _ = draw;
    }

    /// The checks of a draw decoded from a record: θ inside the box, and what the
    /// optimizer remembers of it finite and in range.
    fn check_draw(&self, draw: &Draw<N>) -> Result<(), Error> {
        self.bounds().check(&draw.theta, "in_flight")
    }
}

/// Where a slot of the generation stands.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
enum Slot {
    /// Handed out under this ticket.
    Out(Ticket),
    /// Its cost, held until the earlier slots have theirs.
    Reported(f32),
    /// Its ticket was cancelled: hand the candidate out again.
    Returned,
}

/// An optimizer with up to `C` candidates in flight (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct InFlight<O, const N: usize, const C: usize> {
    optimizer: O,
    /// The generation's candidates not yet told to the optimizer, in hand-out order: the
    /// first is the next one the optimizer's `tell` takes.
    slots: Vec<(Draw<N>, Slot), C>,
    next_ticket: u32,
}

impl<O: Generation<N>, const N: usize, const C: usize> InFlight<O, N, C> {
    /// `optimizer` with nothing in flight yet.
    pub const fn new(optimizer: O) -> Self {
        const { assert!(C >= 1, "room for at least one candidate in flight") };
        Self {
            optimizer,
            slots: Vec::new(),
            next_ticket: 0,
        }
    }

    /// The optimizer, in the state the told costs have brought it to. Its record (with the
    /// `serde` feature) is the one firmware loads.
    pub fn optimizer(&self) -> &O {
        &self.optimizer
    }

    /// The optimizer, when nothing is in flight; else `self` back.
    pub fn into_optimizer(self) -> Result<O, Self> {
        if self.slots.is_empty() {
            Ok(self.optimizer)
        } else {
            Err(self)
        }
    }

    /// Whether nothing is in flight: no ticket out, no cost held, no cancelled candidate
    /// waiting. Then every reported cost has reached the optimizer, the sequential `ask`
    /// and `tell` work, and [`InFlight::optimizer`]'s record is complete.
    pub fn idle(&self) -> bool {
        self.slots.is_empty()
    }

    /// The most candidates this optimizer can ever have in flight at once: the smaller of
    /// `C` and [`Generation::most`] (1 for a sequential optimizer).
    pub fn max_in_flight(&self) -> usize {
        C.min(self.optimizer.most())
    }

    /// How many more [`InFlight::suggest`] calls return a candidate now: cancelled ones
    /// first, then the rest of the generation that fits in `C`. 0 once stopped, or while a
    /// sequential `ask` is pending.
    pub fn capacity(&self) -> usize {
        if self.optimizer.status() != Status::Running || self.sequential_pending() {
            return 0;
        }
        let returned = self
            .slots
            .iter()
            .filter(|(_, s)| *s == Slot::Returned)
            .count();
        let window = C.min(self.optimizer.room());
        returned + window.saturating_sub(self.slots.len())
    }

    /// The outstanding tickets, in hand-out order.
    pub fn in_flight(&self) -> impl Iterator<Item = Ticket> + '_ {
        self.slots.iter().filter_map(|(_, s)| match s {
            Slot::Out(t) => Some(*t),
            _ => None,
        })
    }

    /// The candidate of an outstanding ticket.
    pub fn candidate(&self, ticket: Ticket) -> Option<&Vector<N>> {
        self.slots
            .iter()
            .find(|(_, s)| *s == Slot::Out(ticket))
            .map(|(d, _)| &d.theta)
    }

    /// The next candidate (inside the box) and its ticket: a cancelled candidate again, or
    /// the next of the generation; `None` when [`InFlight::capacity`] is 0 with the search
    /// running. [`Error::Stopped`] once it has stopped; [`Error::CandidatePending`] while a
    /// sequential `ask` waits for its `tell`.
    pub fn suggest<R: RngCore + ?Sized>(
        &mut self,
        rng: &mut R,
    ) -> Result<Option<(Ticket, Vector<N>)>, Error> {
        if self.optimizer.status() != Status::Running {
            return Err(Error::Stopped);
        }
        if self.sequential_pending() {
            return Err(Error::CandidatePending);
        }
        let ticket = self.fresh_ticket();
        if let Some((draw, slot)) = self.slots.iter_mut().find(|(_, s)| *s == Slot::Returned) {
            *slot = Slot::Out(ticket);
            self.next_ticket = ticket.0.wrapping_add(1);
            return Ok(Some((ticket, draw.theta)));
        }
        let ahead = self.slots.len();
        if ahead >= C.min(self.optimizer.room()) {
            return Ok(None);
        }
        let draw = self.optimizer.draw(ahead, rng)?;
        // ahead < C: the push succeeds.
        if self.slots.push((draw, Slot::Out(ticket))).is_err() {
            return Ok(None);
        }
        self.next_ticket = ticket.0.wrapping_add(1);
        Ok(Some((ticket, draw.theta)))
    }

    /// The optimizer's pending candidate under a ticket, as [`InFlight::suggest`] hands out
    /// a candidate: for one made pending before the wrapper took over, such as the start
    /// of [`ControlledRandomSearch::try_with_start`](super::ControlledRandomSearch::try_with_start)
    /// or [`Sracos::try_with_start`](super::Sracos::try_with_start). `None` (nothing changed)
    /// unless the search runs, nothing is in flight, a candidate is pending and the optimizer
    /// [adopts](Generation::adopts_pending) it; later `suggest`s continue the generation.
    pub fn adopt_pending(&mut self) -> Option<(Ticket, Vector<N>)> {
        if self.optimizer.status() != Status::Running
            || !self.sequential_pending()
            || !self.optimizer.adopts_pending()
        {
            return None;
        }
        let theta = *self.optimizer.pending()?;
        let ticket = self.fresh_ticket();
        self.slots.push((Draw::of(theta), Slot::Out(ticket))).ok()?;
        self.next_ticket = ticket.0.wrapping_add(1);
        Some((ticket, theta))
    }

    /// The cost of `ticket`'s candidate. It reaches the optimizer once every candidate
    /// handed out before it in the generation has its cost (so the result does not depend
    /// on the order of the reports). [`Error::UnknownTicket`] for a ticket not outstanding,
    /// [`Error::NonFinite`] for a NaN or infinite cost; both change nothing.
    pub fn report(&mut self, ticket: Ticket, cost: f32) -> Result<(), Error> {
        let index = self.index_of(ticket)?;
        if !cost.is_finite() {
            return Err(Error::NonFinite("cost"));
        }
        if let Some((_, slot)) = self.slots.get_mut(index) {
            *slot = Slot::Reported(cost);
        }
        self.tell_ready()
    }

    /// Gives `ticket` back (its episode failed): a later [`InFlight::suggest`] hands the
    /// same candidate out again under a new ticket. [`Error::UnknownTicket`] for a ticket
    /// not outstanding.
    pub fn cancel(&mut self, ticket: Ticket) -> Result<(), Error> {
        let index = self.index_of(ticket)?;
        if let Some((_, slot)) = self.slots.get_mut(index) {
            *slot = Slot::Returned;
        }
        Ok(())
    }

    fn index_of(&self, ticket: Ticket) -> Result<usize, Error> {
        self.slots
            .iter()
            .position(|(_, s)| *s == Slot::Out(ticket))
            .ok_or(Error::UnknownTicket)
    }

    /// A pending candidate from the sequential `ask`, with nothing handed out by `suggest`.
    fn sequential_pending(&self) -> bool {
        self.slots.is_empty() && self.optimizer.pending().is_some()
    }

    /// The next ticket number not outstanding (numbers wrap after 2³²).
    fn fresh_ticket(&self) -> Ticket {
        let mut number = self.next_ticket;
        while self
            .slots
            .iter()
            .any(|(_, s)| *s == Slot::Out(Ticket(number)))
        {
            number = number.wrapping_add(1);
        }
        Ticket(number)
    }

    /// Tells the optimizer the held costs at the front of the generation, in hand-out order.
    fn tell_ready(&mut self) -> Result<(), Error> {
        let mut told = 0;
        let mut result = Ok(());
        for (draw, slot) in &self.slots {
            let Slot::Reported(cost) = *slot else { break };
            self.optimizer.resume(draw);
            result = self.optimizer.tell(cost);
            if result.is_err() {
                break;
            }
            told += 1;
        }
        self.slots = Vec::from_slice(self.slots.get(told..).unwrap_or(&[])).unwrap_or_default();
        // A generation ends at a stop (the budget, convergence at an update) and slots never
        // outlive it; a state that says otherwise drops them rather than keep tickets that
        // could never be told.
        if result.is_err() || self.optimizer.status() != Status::Running {
            self.slots.clear();
        }
        result
    }

    /// The checks of a decoded value ([`Persistent::validate`](crate::record::Persistent)):
    /// the optimizer's, then the slots': no more than the generation's room, each draw
    /// checked by the optimizer, held costs finite and never first (they would have been
    /// told), outstanding tickets distinct, and a pending candidate of the optimizer only
    /// as the first draw in flight, an `ask`-made or adopted one.
    #[cfg(feature = "serde")]
    pub(crate) fn check_decoded(&self) -> Result<(), Error>
    where
        O: crate::record::Persistent,
    {
        use crate::error::require;
        self.optimizer.validate()?;
        require(
            self.slots.len() <= C.min(self.optimizer.room()),
            "in_flight",
        )?;
        for (i, (draw, slot)) in self.slots.iter().enumerate() {
            self.optimizer.check_draw(draw)?;
            match *slot {
                Slot::Reported(cost) => {
                    require(cost.is_finite() && i > 0, "in_flight")?;
                }
                Slot::Out(ticket) => require(
                    self.slots
                        .iter()
                        .filter(|(_, s)| *s == Slot::Out(ticket))
                        .count()
                        == 1,
                    "in_flight",
                )?,
                Slot::Returned => {}
            }
        }
        let consistent = match (self.optimizer.pending(), self.slots.first()) {
            (Some(p), Some((draw, _))) => self.optimizer.adopts_pending() && *p == draw.theta,
            (Some(_), None) => true,
            (None, Some(_)) => self.optimizer.draws_ahead(),
            (None, None) => true,
        };
        require(consistent, "in_flight")
    }
}

/// The sequential contract, while nothing is in flight.
impl<O: Generation<N>, const N: usize, const C: usize> Optimizer<N> for InFlight<O, N, C> {
    /// The optimizer's `ask`; [`Error::InFlight`] while tickets are outstanding.
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        if !self.slots.is_empty() {
            return Err(Error::InFlight);
        }
        self.optimizer.ask(rng)
    }

    /// The optimizer's `tell`; [`Error::InFlight`] while tickets are outstanding.
    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        if !self.slots.is_empty() {
            return Err(Error::InFlight);
        }
        self.optimizer.tell(cost)
    }

    fn best(&self) -> Option<Best<N>> {
        self.optimizer.best()
    }

    /// The sequential `ask`'s pending candidate (none while tickets are outstanding).
    fn pending(&self) -> Option<&Vector<N>> {
        if self.slots.is_empty() {
            self.optimizer.pending()
        } else {
            None
        }
    }

    fn evaluations(&self) -> u32 {
        self.optimizer.evaluations()
    }

    fn status(&self) -> Status {
        self.optimizer.status()
    }

    fn bounds(&self) -> &Bounds<N> {
        self.optimizer.bounds()
    }
}

// The sequential optimizers: one candidate at a time, drawn by `ask` (the defaults).
impl<const N: usize> Generation<N> for super::CoordinateSearch<N> {}
impl<const N: usize, const K: usize, const M: usize> Generation<N> for super::Sracos<N, K, M> {}
impl<const N: usize, const K: usize, const M: usize> Generation<N> for super::Racos<N, K, M> {}
impl<const N: usize, const M: usize> Generation<N> for super::LineBo<N, M> {}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use crate::optimizer::{
        AnyOptimizer, CemConfig, ControlledRandomSearch, CrsConfig, DiagonalCem, Racos, Rockstar,
        RockstarConfig, SracosConfig,
    };
    use crate::testing::{every_optimizer, rng};
    use proptest::prelude::*;
    use rand_core::RngCore;

    type Any3 = AnyOptimizer<3, 4, 2, 5, 8>;

    /// A cost with many ties (quarters), so that the order of equal costs matters.
    fn cost(theta: &Vector<3>) -> f32 {
        let c: f32 = theta.iter().map(|t| (t - 0.3) * (t - 0.3)).sum();
        libm::roundf(c * 4.0) / 4.0
    }

    /// Drives `flight` with random suggests, reports (in random order), cancellations and
    /// rejected calls, chosen by `script`, for `steps` steps; beside it a copy of the
    /// optimizer takes the same candidates by the sequential `ask`/`tell`, in hand-out
    /// order. Checks on the way: every rejected call changes nothing; the capacity is
    /// what `suggest` delivers; at most `max_in_flight` tickets are out; and whenever
    /// nothing is in flight the wrapped optimizer and the RNG equal the sequential ones.
    fn check_against_sequential<O, const C: usize>(optimizer: O, script: u64, steps: usize)
    where
        O: Generation<3> + Clone + PartialEq + core::fmt::Debug,
    {
        let mut sequential = optimizer.clone();
        let mut flight = InFlight::<O, 3, C>::new(optimizer);
        let (mut r_flight, mut r_seq, mut choose) = (rng(7), rng(7), rng(script));
        // The new candidates in hand-out order, and how many the sequential run has taken.
        let mut drawn: Vec<Vector<3>> = Vec::new();
        let mut out: Vec<(Ticket, Vector<3>)> = Vec::new();
        let mut compared = 0;
        for _ in 0..steps {
            let before = flight.clone();
            match choose.next_u32() % 8 {
                0..=3 => {
                    let capacity = flight.capacity();
                    match flight.suggest(&mut r_flight) {
                        Ok(Some((ticket, theta))) => {
                            assert!(capacity > 0);
                            assert!(flight.bounds().contains(&theta));
                            let reissued = before
                                .slots
                                .iter()
                                .any(|(d, s)| *s == Slot::Returned && d.theta == theta);
                            if !reissued {
                                drawn.push(theta);
                            }
                            assert_eq!(flight.capacity(), capacity - 1);
                            out.push((ticket, theta));
                        }
                        Ok(None) => {
                            assert_eq!(capacity, 0);
                            assert_eq!(flight, before);
                        }
                        Err(e) => {
                            assert_eq!(e, Error::Stopped);
                            assert_eq!(flight, before);
                        }
                    }
                }
                4..=6 if !out.is_empty() => {
                    let i = choose.next_u32() as usize % out.len();
                    let (ticket, theta) = out.swap_remove(i);
                    assert_eq!(flight.candidate(ticket), Some(&theta));
                    if choose.next_u32() % 6 == 0 {
                        flight.cancel(ticket).unwrap();
                    } else {
                        assert_eq!(
                            flight.report(ticket, f32::NAN),
                            Err(Error::NonFinite("cost"))
                        );
                        assert_eq!(flight, before);
                        flight.report(ticket, cost(&theta)).unwrap();
                        assert_eq!(flight.report(ticket, 1.0), Err(Error::UnknownTicket));
                    }
                }
                _ => {
                    // Calls that must be refused without change.
                    assert_eq!(
                        flight.report(Ticket(u32::MAX), 1.0),
                        Err(Error::UnknownTicket)
                    );
                    assert_eq!(flight.cancel(Ticket(u32::MAX)), Err(Error::UnknownTicket));
                    if !flight.slots.is_empty() {
                        assert_eq!(flight.ask(&mut r_flight), Err(Error::InFlight));
                        assert_eq!(flight.tell(1.0), Err(Error::InFlight));
                    }
                    assert_eq!(flight, before);
                }
            }
            assert!(flight.in_flight().count() <= flight.max_in_flight());
            assert_eq!(flight.in_flight().count(), out.len());
            if flight.slots.is_empty() {
                for theta in &drawn[compared..] {
                    assert_eq!(sequential.ask(&mut r_seq).as_ref(), Ok(theta));
                    sequential.tell(cost(theta)).unwrap();
                }
                compared = drawn.len();
                assert_eq!(flight.optimizer(), &sequential);
                assert_eq!(r_flight, r_seq);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// Checks, for every optimizer (and batch RACOS) with room for 1, 3 or 16 in flight,
        /// over random interleavings of suggests, reports in any order, cancellations and
        /// refused calls: whenever nothing is in flight, the optimizer and the RNG are
        /// exactly those of the sequential `ask`/`tell` with the same costs (see
        /// `check_against_sequential` for the checks on the way).
        #[test]
        fn any_report_order_gives_the_sequential_state(script in any::<u64>()) {
            for optimizer in every_optimizer() {
                check_against_sequential::<Any3, 1>(optimizer.clone(), script, 150);
                check_against_sequential::<Any3, 3>(optimizer.clone(), script, 150);
                check_against_sequential::<Any3, 16>(optimizer, script, 150);
            }
            let b = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
            let racos: Racos<3> = Racos::try_new(b, SracosConfig::DEFAULT).unwrap();
            check_against_sequential::<_, 4>(racos, script, 150);
        }
    }

    /// Checks the capacities of the module table: a CEM's whole batch, a CMA-ES generation,
    /// CRS's set while it fills and then 1, ROCK*'s initial samples and then 1, 1 for the
    /// sequential ones; never more than `C` nor than the budget left.
    #[test]
    fn capacity_is_the_rest_of_the_generation() {
        let optimizers = every_optimizer();
        let most: Vec<usize> = optimizers
            .iter()
            .map(|o| InFlight::<_, 3, 64>::new(o.clone()).max_in_flight())
            .collect();
        // Coordinate, CRS, TwoPhase (its CRS), SRACOS, CEM, CMA-ES ×2, ROCK*, LineBO ×3.
        assert_eq!(most, [1, 5, 5, 1, 4, 4, 4, 2, 1, 1, 1]);
        for o in optimizers {
            let mut flight = InFlight::<_, 3, 64>::new(o);
            assert_eq!(flight.capacity(), flight.max_in_flight());
            let mut r = rng(1);
            let mut tickets = Vec::new();
            while let Some((t, theta)) = flight.suggest(&mut r).unwrap() {
                tickets.push((t, theta));
            }
            assert_eq!(tickets.len(), flight.max_in_flight());
            for (t, theta) in tickets {
                flight.report(t, cost(&theta)).unwrap();
            }
        }
        // After Step 0, CRS and ROCK* take one at a time.
        let b = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
        let crs: ControlledRandomSearch<3, 5> =
            ControlledRandomSearch::try_new(b, CrsConfig::DEFAULT).unwrap();
        let rock: Rockstar<3, 5> =
            Rockstar::try_new(b, Vector::zeros(), RockstarConfig::DEFAULT).unwrap();
        let (mut crs, mut rock) = (
            InFlight::<_, 3, 8>::new(crs),
            InFlight::<_, 3, 8>::new(rock),
        );
        let mut r = rng(2);
        for _ in 0..5 {
            let theta = crs.ask(&mut r).unwrap();
            crs.tell(cost(&theta)).unwrap();
        }
        for _ in 0..2 {
            let theta = rock.ask(&mut r).unwrap();
            rock.tell(cost(&theta)).unwrap();
        }
        assert_eq!((crs.capacity(), rock.capacity()), (1, 1));
        // The budget caps it, and C does.
        let cfg = CemConfig {
            max_evaluations: 3,
            ..CemConfig::DEFAULT
        };
        let cem = DiagonalCem::<3, 6>::try_new(b, Vector::zeros(), cfg).unwrap();
        assert_eq!(InFlight::<_, 3, 8>::new(cem.clone()).capacity(), 3);
        assert_eq!(InFlight::<_, 3, 2>::new(cem).capacity(), 2);
    }

    /// Checks a start given to CRS (and SRACOS, and a two-phase search over such a CRS):
    /// the first `ask` returns it; a record saved at once loads back equal; under
    /// `InFlight` it goes out first by `adopt_pending` (not by `suggest`, refused while it
    /// is pending), the rest of CRS's set follows by `suggest`, and reported in reverse
    /// order the state is the sequential run's. A start outside the box is refused.
    #[test]
    #[cfg(feature = "serde")]
    fn a_start_is_the_first_candidate_and_goes_out_under_a_ticket() {
        use crate::optimizer::{CoordinateConfig, Sracos, TwoPhase};
        let b = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
        let start = Vector::from([0.25, -0.5, 0.75]);
        assert_eq!(
            ControlledRandomSearch::<3, 5>::try_with_start(b, CrsConfig::DEFAULT, [2.0; 3].into()),
            Err(Error::OutOfBounds("start"))
        );
        assert_eq!(
            Sracos::<3>::try_with_start(b, SracosConfig::DEFAULT, [f32::NAN; 3].into()),
            Err(Error::NonFinite("start"))
        );
        let crs =
            ControlledRandomSearch::<3, 5>::try_with_start(b, CrsConfig::DEFAULT, start).unwrap();
        let sracos = Sracos::<3>::try_with_start(b, SracosConfig::DEFAULT, start).unwrap();
        let two = TwoPhase::try_new(crs.clone(), 8, CoordinateConfig::DEFAULT).unwrap();
        let optimizers: [Any3; 3] = [crs.into(), sracos.into(), two.into()];
        for optimizer in optimizers {
            assert_eq!(optimizer.pending(), Some(&start));
            let mut buf = [0u8; 4096];
            let bytes = crate::record::save(&optimizer, &mut buf).unwrap();
            assert_eq!(crate::record::load::<Any3>(bytes).as_ref(), Ok(&optimizer));
            let mut sequential = optimizer.clone();
            let mut flight = InFlight::<_, 3, 8>::new(optimizer);
            let (mut r, mut r_seq) = (rng(3), rng(3));
            assert_eq!(flight.suggest(&mut r), Err(Error::CandidatePending));
            let mut out = Vec::new();
            out.push(flight.adopt_pending().unwrap());
            assert_eq!(flight.adopt_pending(), None);
            while let Some(pair) = flight.suggest(&mut r).unwrap() {
                out.push(pair);
            }
            assert_eq!(out.first().map(|(_, t)| *t), Some(start));
            let mut bytes = [0u8; 4096];
            let saved = crate::record::save(&flight, &mut bytes).unwrap();
            assert_eq!(
                crate::record::load::<InFlight<Any3, 3, 8>>(saved).as_ref(),
                Ok(&flight)
            );
            for (ticket, theta) in out.iter().rev() {
                flight.report(*ticket, cost(theta)).unwrap();
            }
            for (_, theta) in &out {
                assert_eq!(sequential.ask(&mut r_seq).as_ref(), Ok(theta));
                sequential.tell(cost(theta)).unwrap();
            }
            assert_eq!(flight.optimizer(), &sequential);
        }
    }

    /// Checks the size the docs give: a slot of the wrapper is 8N + 12 bytes (θ, what the
    /// optimizer remembers of the draw, the ticket or held cost), at N = 1, 18 and 64.
    #[test]
    fn a_slot_is_8n_plus_12_bytes() {
        use core::mem::size_of;
        assert_eq!(size_of::<(Draw<1>, Slot)>(), 20);
        assert_eq!(size_of::<(Draw<18>, Slot)>(), 8 * 18 + 12);
        assert_eq!(size_of::<(Draw<64>, Slot)>(), 8 * 64 + 12);
    }

    /// Checks the errors: `suggest` on a stopped search is `Stopped`, and while a
    /// sequential `ask` is pending `CandidatePending` (and the capacity 0); the sequential
    /// calls work when nothing is in flight; a cancelled ticket is unknown afterwards and
    /// its candidate comes back under a new ticket.
    #[test]
    fn errors_and_mixing() {
        let b = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
        let cfg = CemConfig {
            max_evaluations: 4,
            ..CemConfig::DEFAULT
        };
        let cem = DiagonalCem::<3, 6>::try_new(b, Vector::zeros(), cfg).unwrap();
        let mut flight = InFlight::<_, 3, 8>::new(cem);
        let mut r = rng(3);
        let theta = flight.ask(&mut r).unwrap();
        assert_eq!(flight.capacity(), 0);
        let before = flight.clone();
        assert_eq!(flight.suggest(&mut r), Err(Error::CandidatePending));
        assert_eq!(flight, before);
        flight.tell(cost(&theta)).unwrap();
        let (t1, a) = flight.suggest(&mut r).unwrap().unwrap();
        let (t2, _) = flight.suggest(&mut r).unwrap().unwrap();
        assert_ne!(t1, t2);
        flight.cancel(t1).unwrap();
        assert_eq!(flight.cancel(t1), Err(Error::UnknownTicket));
        assert_eq!(flight.report(t1, 1.0), Err(Error::UnknownTicket));
        assert_eq!(flight.in_flight().collect::<Vec<_>>(), [t2]);
        let (t3, again) = flight.suggest(&mut r).unwrap().unwrap();
        assert_eq!(again, a);
        assert!(t3 != t1 && t3 != t2);
        let (t4, _) = flight.suggest(&mut r).unwrap().unwrap();
        assert_eq!(flight.suggest(&mut r), Ok(None), "the budget of 4 is out");
        for t in [t4, t2, t3] {
            flight.report(t, 1.0).unwrap();
        }
        assert_eq!(flight.status(), Status::BudgetSpent);
        assert_eq!(flight.suggest(&mut r), Err(Error::Stopped));
        assert_eq!(flight.capacity(), 0);
    }

    /// Checks: a record saved with tickets out and costs held restores them: the restored
    /// value accepts the outstanding tickets and ends the generation in the state of the
    /// one that was not saved; a record whose slots contradict the optimizer is refused.
    #[cfg(feature = "serde")]
    #[test]
    fn records_keep_the_tickets() {
        use crate::record::{self, RecordError};
        for o in every_optimizer() {
            let mut flight = InFlight::<Any3, 3, 4>::new(o);
            let mut r = rng(5);
            let mut out = Vec::new();
            while let Some(t) = flight.suggest(&mut r).unwrap() {
                out.push(t);
            }
            // The last one reported (held unless it is the only one), the first cancelled.
            if let Some(&(t, theta)) = out.last() {
                flight.report(t, cost(&theta)).unwrap();
            }
            if out.len() > 1 {
                flight.cancel(out[0].0).unwrap();
            }
            let mut buf = [0u8; 8192];
            let bytes = record::save(&flight, &mut buf).unwrap();
            let mut restored: InFlight<Any3, 3, 4> = record::load(bytes).unwrap();
            assert_eq!(restored, flight);
            for f in [&mut flight, &mut restored] {
                let mut r = rng(6);
                if out.len() > 1 {
                    let (t, theta) = f.suggest(&mut r).unwrap().unwrap();
                    assert_eq!(theta, out[0].1);
                    f.report(t, cost(&theta)).unwrap();
                }
                for &(t, theta) in out.get(1..out.len().saturating_sub(1)).unwrap_or(&[]) {
                    f.report(t, cost(&theta)).unwrap();
                }
                assert_eq!(f.in_flight().count(), 0);
            }
            assert_eq!(restored, flight);
        }
        // A held cost first (it would have been told) is refused.
        let b = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
        let cem = DiagonalCem::<3, 6>::try_new(b, Vector::zeros(), CemConfig::DEFAULT).unwrap();
        let mut flight = InFlight::<_, 3, 4>::new(cem);
        let (t, _) = flight.suggest(&mut rng(1)).unwrap().unwrap();
        let mut forged = flight.clone();
        forged.slots[0].1 = Slot::Reported(1.0);
        let mut buf = [0u8; 4096];
        let bytes = record::save_unchecked(&forged, &mut buf).unwrap();
        assert_eq!(
            record::load::<InFlight<DiagonalCem<3, 6>, 3, 4>>(bytes),
            Err(RecordError::Invalid(Error::InvalidParameter("in_flight")))
        );
        // So is a slot outside the box.
        let mut forged = flight;
        forged.slots[0].0.theta[0] = 2.0;
        let bytes = record::save_unchecked(&forged, &mut buf).unwrap();
        assert!(record::load::<InFlight<DiagonalCem<3, 6>, 3, 4>>(bytes).is_err());
        let _ = t;
    }
}
