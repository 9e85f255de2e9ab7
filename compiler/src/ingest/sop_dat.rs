//! sop_dat: reader being written.
