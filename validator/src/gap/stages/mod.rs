//! The workflow's stages, in the order that keeps effects from masquerading as each other
//! (see the [`gap`](super) module docs): [`geometry`], [`blur`], [`photometry`], [`shadows`],
//! [`texture`], [`noise`]. Each takes the run's context, may add effects to the model it is
//! given, and pushes what it named with its evidence; the fits and measurements themselves live
//! in the modules of the same names one level up, so that a stage file reads as the decision
//! it makes: which candidates, which witness, which floor, which standard error.

pub(crate) mod blur;
pub(crate) mod geometry;
pub(crate) mod noise;
pub(crate) mod photometry;
pub(crate) mod shadows;
pub(crate) mod texture;
