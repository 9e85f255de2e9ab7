//! las: reader being written.
