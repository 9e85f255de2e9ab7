//! calib_bouguet: reader being written.
