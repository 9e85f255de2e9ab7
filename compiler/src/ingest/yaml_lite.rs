//! yaml_lite: reader being written.
