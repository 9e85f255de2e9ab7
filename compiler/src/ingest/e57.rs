//! e57: reader being written.
