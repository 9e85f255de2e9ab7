//! riscan_ascii: reader being written.
