//! calib_opencv: reader being written.
