//! tiepoints: reader being written.
