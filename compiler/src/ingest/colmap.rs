//! colmap: reader being written.
