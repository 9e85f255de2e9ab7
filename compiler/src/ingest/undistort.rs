//! undistort: reader being written.
