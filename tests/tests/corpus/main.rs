//! The corpus generator's self-checks: formats, determinism, truth consistency and the hidden
//! effects' presence. Campaigns here are made with the validator-model captures
//! (`regolith-model-captures`): these checks compare the corpus's data with its own truth,
//! not the validator with reality.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
mod determinism;
mod formats;
mod hidden_effects;
mod selfcheck;
