//! Sensor effect model (being written).
