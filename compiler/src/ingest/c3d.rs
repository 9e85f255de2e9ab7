//! c3d: reader being written.
