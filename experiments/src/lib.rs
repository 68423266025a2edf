//! Research on top of the host harness: the hopping studies, tuning sweeps and long
//! reproductions of the papers' tables. Not part of the product: nothing here is needed to
//! use the library, and the findings live in `findings/`. CI builds this crate and runs its
//! release-only claims (`cargo test --release -p experiments`).

pub mod auv_guard;
pub mod hopping;
pub mod model_learner;
pub mod overhead;
pub mod peers;
pub mod rockstar_arm;
