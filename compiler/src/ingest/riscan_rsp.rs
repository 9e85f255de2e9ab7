//! riscan_rsp: reader being written.
