//! Helpers shared by the unit tests: one home instead of a copy in each test module.

use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// The tests' RNG, seeded (xoshiro128++, as in the firmware examples).
pub(crate) fn rng(seed: u64) -> Xoshiro128PlusPlus {
    Xoshiro128PlusPlus::seed_from_u64(seed)
}
