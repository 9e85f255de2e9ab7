//! The one camera model of the format: pinhole with Brown–Conrady distortion (SPEC.md §6).
//!
//! Pixel convention: `(0, 0)` is the **centre** of the top-left pixel, as in OpenCV; x grows to
//! the right, y downwards. Every ingest reader converts its source's convention to this one
//! (COLMAP differs by half a pixel; Bouguet's `cc` already uses this convention, see
//! `campaign.md`). With normalised coordinates `x = X/Z`,
//! `y = Y/Z` and `r² = x² + y²`:
//!
//! ```text
//! x_d = x (1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2 x²)
//! y_d = y (1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2 y²) + 2 p2 x y
//! u   = fx x_d + skew y_d + cx
//! v   = fy y_d + cy
//! ```

use serde::{Deserialize, Serialize};

use crate::FormatError;

/// The model id stored in JSON.
pub const MODEL_ID: &str = "pinhole-brown-conrady";

/// Intrinsics of one camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraModel {
    /// Always [`MODEL_ID`].
    pub model: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels (pixel-centre convention).
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Skew `K[0][1]` in pixels (0 for square pixels).
    #[serde(default)]
    pub skew: f64,
    /// Radial and tangential coefficients.
    pub distortion: Distortion,
}

/// A projected pixel and its derivatives ([`CameraModel::project_with_jacobian`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectionJacobian {
    /// The pixel, as [`CameraModel::project`] gives it.
    pub pixel: [f64; 2],
    /// ∂(u, v)/∂(X, Y, Z): row 0 u, row 1 v.
    pub point: [[f64; 3]; 2],
    /// ∂(u, v)/∂(k1, k2): row 0 u, row 1 v.
    pub radial: [[f64; 2]; 2],
}

/// Brown–Conrady coefficients in OpenCV order.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Distortion {
    /// Radial r².
    pub k1: f64,
    /// Radial r⁴.
    pub k2: f64,
    /// Tangential.
    pub p1: f64,
    /// Tangential.
    pub p2: f64,
    /// Radial r⁶.
    pub k3: f64,
}

impl CameraModel {
    /// A distortion-free pinhole camera.
    pub fn pinhole(width: u32, height: u32, fx: f64, fy: f64, cx: f64, cy: f64) -> CameraModel {
        CameraModel {
            model: MODEL_ID.to_string(),
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            skew: 0.0,
            distortion: Distortion::default(),
        }
    }

    /// Checks ranges: positive size and focal lengths, finite values, known model id.
    pub fn validate(&self) -> Result<(), FormatError> {
        let d = self.distortion;
        let all = [
            self.fx, self.fy, self.cx, self.cy, self.skew, d.k1, d.k2, d.p1, d.p2, d.k3,
        ];
        if self.model != MODEL_ID {
            return Err(FormatError::InvalidCamera(format!(
                "model {:?}: expected {MODEL_ID:?}",
                self.model
            )));
        }
        if self.width == 0 || self.height == 0 {
            return Err(FormatError::InvalidCamera(
                "width and height must be > 0".into(),
            ));
        }
        if !all.iter().all(|v| v.is_finite()) || self.fx <= 0.0 || self.fy <= 0.0 {
            return Err(FormatError::InvalidCamera(
                "fx, fy must be > 0 and every parameter finite".into(),
            ));
        }
        Ok(())
    }

    /// The same camera without distortion (the undistorted images' model).
    pub fn undistorted(&self) -> CameraModel {
        CameraModel {
            distortion: Distortion::default(),
            ..self.clone()
        }
    }

    /// Applies distortion to normalised coordinates.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let d = &self.distortion;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
        (
            x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x),
            y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y,
        )
    }

    /// Normalised distorted coordinates to pixels.
    #[inline]
    pub fn to_pixel(&self, xd: f64, yd: f64) -> [f64; 2] {
        [
            self.fx * xd + self.skew * yd + self.cx,
            self.fy * yd + self.cy,
        ]
    }

    /// Projects a camera-frame point (z forward) to a pixel; `None` behind the camera.
    #[inline]
    pub fn project(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        if p[2] <= 1e-12 {
            return None;
        }
        let (xd, yd) = self.distort(p[0] / p[2], p[1] / p[2]);
        Some(self.to_pixel(xd, yd))
    }

    /// [`CameraModel::project`] with the pixel's derivatives: in the camera-frame point (a
    /// 2 × 3 matrix, rows u and v) and in the radial terms `k1` and `k2` (columns). For fits
    /// that move points or the lens by small increments (the chain rule instead of one
    /// projection per increment).
    #[inline]
    pub fn project_with_jacobian(&self, p: [f64; 3]) -> Option<ProjectionJacobian> {
        if p[2] <= 1e-12 {
            return None;
        }
        let d = &self.distortion;
        let iz = 1.0 / p[2];
        let (x, y) = (p[0] * iz, p[1] * iz);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
        // ∂radial/∂(r²).
        let slope = d.k1 + r2 * (2.0 * d.k2 + 3.0 * r2 * d.k3);
        let xd = x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y;
        // ∂(x_d, y_d)/∂(x, y).
        let cross = 2.0 * x * y * slope + 2.0 * d.p1 * x + 2.0 * d.p2 * y;
        let dxd = [
            radial + 2.0 * x * x * slope + 2.0 * d.p1 * y + 6.0 * d.p2 * x,
            cross,
        ];
        let dyd = [
            cross,
            radial + 2.0 * y * y * slope + 6.0 * d.p1 * y + 2.0 * d.p2 * x,
        ];
        // ∂(x_d, y_d)/∂P through x = X/Z, y = Y/Z.
        let by_point = |row: [f64; 2]| [row[0] * iz, row[1] * iz, -(row[0] * x + row[1] * y) * iz];
        let (gx, gy) = (by_point(dxd), by_point(dyd));
        let mut du = [0.0; 3];
        for ((o, a), b) in du.iter_mut().zip(gx).zip(gy) {
            *o = self.fx * a + self.skew * b;
        }
        let point = [du, gy.map(|b| self.fy * b)];
        let (r4, r2x, r2y) = (r2 * r2, r2 * x, r2 * y);
        Some(ProjectionJacobian {
            pixel: self.to_pixel(xd, yd),
            point,
            radial: [
                [
                    self.fx * r2x + self.skew * r2y,
                    self.fx * r4 * x + self.skew * r4 * y,
                ],
                [self.fy * r2y, self.fy * r4 * y],
            ],
        })
    }

    /// Inverts the distortion: the normalised undistorted coordinates seen at pixel `(u, v)`.
    /// Newton iterations from the distorted point; converges for any physically sensible
    /// distortion within the image.
    pub fn unproject(&self, u: f64, v: f64) -> (f64, f64) {
        let yd = (v - self.cy) / self.fy;
        let xd = (u - self.cx - self.skew * yd) / self.fx;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() < 1e-14 && ey.abs() < 1e-14 {
                break;
            }
            // Numerical Jacobian of the distortion.
            let h = 1e-7;
            let (ax, ay) = self.distort(x + h, y);
            let (bx, by) = self.distort(x, y + h);
            let (j00, j10) = ((ax - fx) / h, (ay - fy) / h);
            let (j01, j11) = ((bx - fx) / h, (by - fy) / h);
            let det = j00 * j11 - j01 * j10;
            if det.abs() < 1e-12 {
                break;
            }
            x -= (j11 * ex - j01 * ey) / det;
            y -= (-j10 * ex + j00 * ey) / det;
        }
        (x, y)
    }

    /// The 3x3 matrix K, row-major.
    pub fn k_matrix(&self) -> [f64; 9] {
        [
            self.fx, self.skew, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0,
        ]
    }

    /// Distortion coefficients in OpenCV order `[k1, k2, p1, p2, k3]`.
    pub fn d_vector(&self) -> [f64; 5] {
        let d = self.distortion;
        [d.k1, d.k2, d.p1, d.p2, d.k3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn the_projection_jacobian_is_the_projections_differences() {
        let cam = navcam();
        let p = [0.4, -0.3, 1.7];
        let j = cam.project_with_jacobian(p);
        assert!(j.is_some());
        let Some(j) = j else { return };
        let at = |c: &CameraModel, q: [f64; 3]| c.project(q).unwrap_or([f64::NAN; 2]);
        assert_eq!(j.pixel, at(&cam, p));
        let h = 1e-6;
        for axis in 0..3 {
            let mut q = p;
            q[axis] += h;
            let (a, b) = (at(&cam, q), at(&cam, p));
            for row in 0..2 {
                let fd = (a[row] - b[row]) / h;
                assert!((fd - j.point[row][axis]).abs() < 1e-3, "{row} {axis}: {fd}");
            }
        }
        for term in 0..2 {
            let mut c = cam.clone();
            if term == 0 {
                c.distortion.k1 += h;
            } else {
                c.distortion.k2 += h;
            }
            let (a, b) = (at(&c, p), at(&cam, p));
            for row in 0..2 {
                let fd = (a[row] - b[row]) / h;
                assert!(
                    (fd - j.radial[row][term]).abs() < 1e-3,
                    "{row} {term}: {fd}"
                );
            }
        }
        assert_eq!(cam.project_with_jacobian([0.0, 0.0, -1.0]), None);
    }

    fn navcam() -> CameraModel {
        CameraModel {
            distortion: Distortion {
                k1: -0.21,
                k2: 0.09,
                p1: 4e-4,
                p2: -2e-4,
                k3: -0.01,
            },
            ..CameraModel::pinhole(1280, 1024, 832.0, 831.0, 639.5, 511.5)
        }
    }

    #[test]
    fn principal_point_projects_to_cx_cy() {
        let c = navcam();
        assert_eq!(c.project([0.0, 0.0, 2.0]), Some([639.5, 511.5]));
        assert_eq!(c.project([0.0, 0.0, -1.0]), None);
        assert!(c.validate().is_ok());
        let mut bad = c.clone();
        bad.fx = f64::NAN;
        assert!(bad.validate().is_err());
    }

    proptest! {
        #[test]
        fn unproject_inverts_project(u in 0.0..1279.0f64, v in 0.0..1023.0f64) {
            let c = navcam();
            let (x, y) = c.unproject(u, v);
            let p = c.project([x, y, 1.0]).unwrap();
            prop_assert!((p[0] - u).abs() < 1e-6 && (p[1] - v).abs() < 1e-6, "{p:?} vs {u} {v}");
        }
    }
}
