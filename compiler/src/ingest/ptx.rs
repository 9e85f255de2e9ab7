//! ptx: reader being written.
