//! Readers for every raw input format a survey campaign brings.
//!
//! One module per format. Each returns typed data from [`types`], streams large inputs, takes
//! [`regolith_format::limits::Limits`], and reports bad input as an [`crate::IngestError`]
//! naming the file, the line or byte offset, and what was expected. None panics on any input
//! (each has a fuzz target in `fuzz/`).

#![deny(clippy::indexing_slicing)]

pub mod c3d;
pub mod calib_bouguet;
pub mod calib_bouguet_mat;
pub mod calib_kalibr;
pub mod calib_opencv;
pub mod calib_ros;
pub mod campaign;
pub mod cmpmvs;
pub mod colmap;
pub mod e57;
pub mod gcp;
pub mod homography;
pub mod images;
pub mod las;
pub mod markers;
pub mod opencv_json;
pub mod opencv_storage;
pub mod ply;
pub mod ptx;
pub mod riscan_ascii;
pub mod riscan_rsp;
pub mod sop_dat;
pub mod tiepoints;
pub mod types;
pub mod undistort;
pub mod vicon_csv;
pub mod vicon_tracker;
pub mod vrml;
pub mod yaml_lite;
