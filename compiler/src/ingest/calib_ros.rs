//! calib_ros: reader being written.
