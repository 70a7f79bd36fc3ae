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
    #[inline]
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
    #[inline]
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
#[inline]
pub fn rotation_matrix(theta: Vector3<f64>) -> Matrix3<f64> {
    let t2 = theta.norm_squared();
    let (a, b) = if t2 < 1e-4 {
        // Taylor series of sin(t)/t and (1 - cos t)/t² to the t^8 term, by Horner with
        // reciprocal factorials; exact in f64 here.
        const A: [f64; 4] = [1.0 / 6.0, 1.0 / 120.0, 1.0 / 5040.0, 1.0 / 362_880.0];
        const B: [f64; 4] = [1.0 / 24.0, 1.0 / 720.0, 1.0 / 40_320.0, 1.0 / 3_628_800.0];
        let a = 1.0 - t2 * (A[0] - t2 * (A[1] - t2 * (A[2] - t2 * A[3])));
        let b = 0.5 - t2 * (B[0] - t2 * (B[1] - t2 * (B[2] - t2 * B[3])));
        (a, b)
    } else {
        let t = t2.sqrt();
        (t.sin() / t, (1.0 - t.cos()) / t2)
    };
    // R = I + a[θ]x + b(θθᵀ - |θ|²I), written out element by element.
    let (x, y, z) = (theta.x, theta.y, theta.z);
    let (bxy, bxz, byz) = (b * x * y, b * x * z, b * y * z);
    let c = 1.0 - b * t2;
    Matrix3::new(
        c + b * x * x,
        bxy - a * z,
        bxz + a * y,
        bxy + a * z,
        c + b * y * y,
        byz - a * x,
        bxz - a * y,
        byz + a * x,
        c + b * z * z,
    )
}
