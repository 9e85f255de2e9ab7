//! calib_kalibr: reader being written.
