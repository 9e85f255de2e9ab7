//! cmpmvs: reader being written.
