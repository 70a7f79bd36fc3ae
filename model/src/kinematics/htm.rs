//! Homogeneous transformation matrices of rigid motions, evaluated exactly in f64.
//!
//! A rigid HTM is `[[R, t], [0, 1]]` with `R` a rotation matrix and `t` a translation (m).
//! [`Htm`] stores the two blocks; [`Htm::compose`] is the 4x4 product and [`Htm::to_matrix4`]
//! gives the full matrix, so chains can be checked against plain 4x4 products.
//!
//! Small rotations (the angular errors of ISO 230-1, rad) are rotation vectors `θ` mapped to a
//! rotation by the exponential map (Rodrigues): `R = I + a [θ]x + b [θ]x²` with
//! `a = sin|θ|/|θ|`, `b = (1 - cos|θ|)/|θ|²`. This is the exact rotation, not the usual
//! first-order `I + [θ]x`: for `|θ| < 1e-2` rad `a` and `b` are evaluated from their Taylor series
//! up to the `|θ|^8` term, whose remainder (below 3e-28 relative) is under f64 resolution, so the
//! result equals the trigonometric form to rounding while avoiding its cancellation.

use nalgebra::{Matrix3, Matrix4, Vector3};

/// A rigid homogeneous transformation: rotation then translation, `p' = R p + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Htm {
    /// Rotation block `R` (orthonormal).
    pub rotation: Matrix3<f64>,
    /// Translation block `t`, m.
    pub translation: Vector3<f64>,
}

impl Htm {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// A pure translation by `t` (m).
    pub fn translation(t: Vector3<f64>) -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: t,
        }
    }

    /// A pure rotation by the rotation vector `theta` (rad, right-hand rule).
    pub fn rotation(theta: Vector3<f64>) -> Self {
        Self {
            rotation: rotation_matrix(theta),
            translation: Vector3::zeros(),
        }
    }

    /// Rotation by `theta` followed by translation by `t`: `[[R(θ), t], [0, 1]]`.
    pub fn new(theta: Vector3<f64>, t: Vector3<f64>) -> Self {
        Self {
            rotation: rotation_matrix(theta),
            translation: t,
        }
    }

    /// Rotation by `theta` about the point `pivot` (m), then translation by `t`.
    pub fn rotation_about(theta: Vector3<f64>, pivot: Vector3<f64>, t: Vector3<f64>) -> Self {
        let rotation = rotation_matrix(theta);
        Self {
            rotation,
            translation: pivot - rotation * pivot + t,
        }
    }

    /// The product `self * other` of the two 4x4 matrices.
    pub fn compose(&self, other: &Htm) -> Htm {
        Htm {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// The exact inverse `[[Rᵀ, -Rᵀ t], [0, 1]]`.
    pub fn inverse(&self) -> Htm {
        let rt = self.rotation.transpose();
        Htm {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// The image of point `p` (m).
    pub fn transform_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.translation
    }

    /// The full 4x4 homogeneous matrix.
    pub fn to_matrix4(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }
}

/// The exact rotation matrix of the rotation vector `theta` (rad), by Rodrigues' formula.
pub fn rotation_matrix(theta: Vector3<f64>) -> Matrix3<f64> {
    let t2 = theta.norm_squared();
    let (a, b) = if t2 < 1e-4 {
        // Taylor series of sin(t)/t and (1 - cos t)/t² to the t^8 term; exact in f64 here.
        let a = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0)));
        let b = 0.5 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0 * (1.0 - t2 / 90.0))));
        (a, b)
    } else {
        let t = t2.sqrt();
        (t.sin() / t, (1.0 - t.cos()) / t2)
    };
    let k = theta.cross_matrix();
    Matrix3::identity() + k * a + k * k * b
}
