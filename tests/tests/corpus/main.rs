//! The corpus generator's self-checks: formats, determinism, truth consistency and the hidden
//! effects' presence. Most campaigns here are made with the validator-model captures
//! (`regolith-model-captures`), which is fine for checks that compare the corpus's data with
//! its own truth; `physical` checks the Mitsuba-rendered campaigns made from the checked-in
//! renders of `corpus/renders/`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
mod determinism;
mod formats;
mod hidden_effects;
mod physical;
mod selfcheck;
