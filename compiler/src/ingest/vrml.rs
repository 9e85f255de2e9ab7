//! vrml: reader being written.
