//! Deterministic CPU renderer (being written).
