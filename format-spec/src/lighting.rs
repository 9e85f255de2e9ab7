//! The lab light as a campaign records it (`[lighting]` in `campaign.toml`, see
//! `format-spec/campaign.md`): a direction toward a distant lamp and an ambient share.
//!
//! Shared vocabulary: the compiler reads it from the campaign, the corpus writes it, the
//! validator renders with it.

/// A distant light (the sun) plus an ambient share.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Light {
    /// Azimuth of the direction toward the light, degrees from +x toward +y.
    pub azimuth_deg: f64,
    /// Elevation of the light above the horizon, degrees.
    pub elevation_deg: f64,
    /// Share of ambient light, 0..1.
    pub ambient: f64,
}
