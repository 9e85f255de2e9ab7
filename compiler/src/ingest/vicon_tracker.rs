//! vicon_tracker: reader being written.
