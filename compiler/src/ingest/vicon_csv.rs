//! vicon_csv: reader being written.
