//! markers: reader being written.
