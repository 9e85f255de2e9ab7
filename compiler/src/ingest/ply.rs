//! ply: reader being written.
