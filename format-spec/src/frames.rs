//! Rigid poses and the frame conventions of SPEC.md §3.
//!
//! A pose named `a_from_b` maps coordinates in frame `b` to frame `a`:
//! `p_a = R * p_b + t`. Cameras use x right, y down, z forward; the ground frame is metres,
//! z up, right-handed. Quaternions are stored x, y, z, w (as glTF, ROS and Foxglove do).
//! The helpers here are deliberately tiny so the format crate needs no linear-algebra crate.

use serde::{Deserialize, Serialize};

/// A rigid transform `p_a = R(q) * p_b + t`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Translation `t` in metres.
    pub translation_m: [f64; 3],
    /// Unit quaternion `q` as `[x, y, z, w]`.
    pub rotation_xyzw: [f64; 4],
}

impl Default for Pose {
    fn default() -> Self {
        Pose::IDENTITY
    }
}

impl Pose {
    /// The identity.
    pub const IDENTITY: Pose = Pose {
        translation_m: [0.0; 3],
        rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
    };

    /// Builds a pose from a row-major rotation matrix and a translation.
    pub fn from_matrix(r: [[f64; 3]; 3], t: [f64; 3]) -> Pose {
        Pose {
            translation_m: t,
            rotation_xyzw: quat_from_matrix(r),
        }
    }

    /// The row-major rotation matrix.
    pub fn rotation_matrix(&self) -> [[f64; 3]; 3] {
        let [x, y, z, w] = normalise(self.rotation_xyzw);
        [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - z * w),
                2.0 * (x * z + y * w),
            ],
            [
                2.0 * (x * y + z * w),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - x * w),
            ],
            [
                2.0 * (x * z - y * w),
                2.0 * (y * z + x * w),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ]
    }

    /// Applies the transform to a point.
    pub fn transform_point(&self, p: [f64; 3]) -> [f64; 3] {
        self.matrix().apply(p)
    }

    /// The transform as a rotation matrix and translation, for applying one pose to many
    /// points without converting the quaternion for each.
    pub fn matrix(&self) -> RigidMatrix {
        RigidMatrix {
            r: self.rotation_matrix(),
            t: self.translation_m,
        }
    }

    /// Rotates a direction (no translation).
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let r = self.rotation_matrix();
        [
            r[0][0] * v[0] + r[0][1] * v[1] + r[0][2] * v[2],
            r[1][0] * v[0] + r[1][1] * v[1] + r[1][2] * v[2],
            r[2][0] * v[0] + r[2][1] * v[1] + r[2][2] * v[2],
        ]
    }

    /// `self * other`: if self is `a_from_b` and other is `b_from_c`, the result is `a_from_c`.
    pub fn compose(&self, other: &Pose) -> Pose {
        let q = quat_mul(
            normalise(self.rotation_xyzw),
            normalise(other.rotation_xyzw),
        );
        let t = self.transform_point(other.translation_m);
        Pose {
            translation_m: t,
            rotation_xyzw: canonical(q),
        }
    }

    /// The inverse transform (`b_from_a` for `a_from_b`).
    pub fn inverse(&self) -> Pose {
        let [x, y, z, w] = normalise(self.rotation_xyzw);
        let qi = [-x, -y, -z, w];
        let ri = Pose {
            translation_m: [0.0; 3],
            rotation_xyzw: qi,
        };
        let t = ri.rotate(self.translation_m);
        Pose {
            translation_m: [-t[0], -t[1], -t[2]],
            rotation_xyzw: canonical(qi),
        }
    }

    /// Rotation angle between two poses, degrees.
    pub fn angle_to_deg(&self, other: &Pose) -> f64 {
        let a = normalise(self.rotation_xyzw);
        let b = normalise(other.rotation_xyzw);
        let dot = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3])
            .abs()
            .min(1.0);
        2.0 * dot.acos().to_degrees()
    }

    /// Translation distance between two poses, metres.
    pub fn distance_to_m(&self, other: &Pose) -> f64 {
        let d = [
            self.translation_m[0] - other.translation_m[0],
            self.translation_m[1] - other.translation_m[1],
            self.translation_m[2] - other.translation_m[2],
        ];
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    }
}

/// A rigid transform `p_a = r * p_b + t` in matrix form ([`Pose::matrix`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidMatrix {
    /// Row-major rotation matrix.
    pub r: [[f64; 3]; 3],
    /// Translation, metres.
    pub t: [f64; 3],
}

impl RigidMatrix {
    /// Applies the transform to a point.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let (r, t) = (&self.r, &self.t);
        [
            r[0][0] * p[0] + r[0][1] * p[1] + r[0][2] * p[2] + t[0],
            r[1][0] * p[0] + r[1][1] * p[1] + r[1][2] * p[2] + t[1],
            r[2][0] * p[0] + r[2][1] * p[1] + r[2][2] * p[2] + t[2],
        ]
    }
}

fn normalise(q: [f64; 4]) -> [f64; 4] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if n > 0.0 && n.is_finite() {
        [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
    } else {
        [0.0, 0.0, 0.0, 1.0]
    }
}

/// Unit quaternion with w >= 0 (q and -q are the same rotation; one is stored).
fn canonical(q: [f64; 4]) -> [f64; 4] {
    let q = normalise(q);
    if q[3] < 0.0 {
        [-q[0], -q[1], -q[2], -q[3]]
    } else {
        q
    }
}

fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let [ax, ay, az, aw] = a;
    let [bx, by, bz, bw] = b;
    [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
}

/// Quaternion `[x, y, z, w]` of a rotation matrix (Shepperd's method), w >= 0.
pub fn quat_from_matrix(r: [[f64; 3]; 3]) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
            0.25 * s,
        ]
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt() * 2.0;
        [
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[2][1] - r[1][2]) / s,
        ]
    } else if r[1][1] > r[2][2] {
        let s = (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt() * 2.0;
        [
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
            (r[0][2] - r[2][0]) / s,
        ]
    } else {
        let s = (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt() * 2.0;
        [
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
            (r[1][0] - r[0][1]) / s,
        ]
    };
    canonical(q)
}

/// Quaternion of a rotation of `angle_rad` about a unit `axis`.
pub fn quat_from_axis_angle(axis: [f64; 3], angle_rad: f64) -> [f64; 4] {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    if n == 0.0 {
        return [0.0, 0.0, 0.0, 1.0];
    }
    let s = (angle_rad / 2.0).sin() / n;
    canonical([
        axis[0] * s,
        axis[1] * s,
        axis[2] * s,
        (angle_rad / 2.0).cos(),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < 1e-9)
    }

    #[test]
    fn rotation_about_z() {
        let p = Pose {
            translation_m: [1.0, 2.0, 3.0],
            rotation_xyzw: quat_from_axis_angle([0.0, 0.0, 1.0], std::f64::consts::FRAC_PI_2),
        };
        assert!(close(p.transform_point([1.0, 0.0, 0.0]), [1.0, 3.0, 3.0]));
    }

    proptest! {
        #[test]
        fn inverse_and_matrix_round_trip(ax in -1.0..1.0f64, ay in -1.0..1.0f64, az in 0.1..1.0f64,
                                          ang in -3.1..3.1f64, t in proptest::array::uniform3(-10.0..10.0f64),
                                          p in proptest::array::uniform3(-5.0..5.0f64)) {
            let pose = Pose { translation_m: t, rotation_xyzw: quat_from_axis_angle([ax, ay, az], ang) };
            let q = pose.inverse().transform_point(pose.transform_point(p));
            prop_assert!(close(q, p));
            let back = Pose::from_matrix(pose.rotation_matrix(), t);
            prop_assert!(close(back.transform_point(p), pose.transform_point(p)));
            let id = pose.compose(&pose.inverse());
            prop_assert!(close(id.transform_point(p), p));
        }
    }
}
