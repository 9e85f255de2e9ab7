//! images: reader being written.
