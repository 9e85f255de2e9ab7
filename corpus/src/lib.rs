//! # regolith-corpus
//!
//! Generates synthetic survey campaigns with full ground truth (being written).
