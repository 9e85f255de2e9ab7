//! The stages of `regolith compile`, one file each, in pipeline order (see `stage.rs`).
pub mod captures;
pub mod delaunay;
pub mod dem_raster;
pub mod dem_regress;
pub mod dem_tin;
pub mod geometry;
pub mod incidence;
pub mod merge_clean;
pub mod radiometry;
pub mod register_icp;
pub mod register_tiepoints;
pub mod self_knn;
pub mod sfm_align;
pub mod sfm_features;
pub mod sfm_height_fit;
