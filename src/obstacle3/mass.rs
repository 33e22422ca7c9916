//! Mass properties of a solid shape of uniform density: mass, centroid (in the shape's frame)
//! and the inertia tensor about the centroid. Sphere, ellipsoid and box in closed form; a mesh
//! by the divergence theorem (signed tetrahedra from the origin, each with the canonical second
//! moment [[2,1,1],[1,2,1],[1,1,2]]/120 mapped by its corner matrix, Tonon 2004).

use super::{Shape3, V3};
use nalgebra::Matrix3;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProperties {
    pub mass: f64,
    pub centroid: V3,
    /// Inertia tensor about the centroid, in the shape's frame.
    pub inertia: Matrix3<f64>,
}

/// Mass properties of `shape` filled with `density`; `None` for the unbounded half-space.
pub fn mass_properties(shape: &Shape3, density: f64) -> Option<MassProperties> {
    let pi = std::f64::consts::PI;
    let diag = |m: f64, a: f64, b: f64, c: f64, k: f64| {
        Matrix3::from_diagonal(&V3::new(
            k * m * (b * b + c * c),
            k * m * (a * a + c * c),
            k * m * (a * a + b * b),
        ))
    };
    Some(match shape {
        Shape3::Sphere { radius: r } => {
            let m = density * 4.0 / 3.0 * pi * r * r * r;
            MassProperties {
                mass: m,
                centroid: V3::zeros(),
                inertia: Matrix3::identity() * (0.4 * m * r * r),
            }
        }
        Shape3::Ellipsoid {
            semi_axes: [a, b, c],
        } => {
            let m = density * 4.0 / 3.0 * pi * a * b * c;
            MassProperties {
                mass: m,
                centroid: V3::zeros(),
                inertia: diag(m, *a, *b, *c, 0.2),
            }
        }
        Shape3::Box { half: [a, b, c] } => {
            let m = density * 8.0 * a * b * c;
            // (2a)² / 12 = a² / 3.
            MassProperties {
                mass: m,
                centroid: V3::zeros(),
                inertia: diag(m, *a, *b, *c, 1.0 / 3.0),
            }
        }
        Shape3::Mesh(mesh) => {
            let canon = Matrix3::new(2.0, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 2.0) / 120.0;
            let (mut vol, mut first, mut second) = (0.0, V3::zeros(), Matrix3::zeros());
            for t in &mesh.triangles {
                let (a, b, c) = (
                    mesh.vertices[t[0]],
                    mesh.vertices[t[1]],
                    mesh.vertices[t[2]],
                );
                let corners = Matrix3::from_columns(&[a, b, c]);
                let det = corners.determinant();
                vol += det / 6.0;
                first += det / 24.0 * (a + b + c);
                second += det * corners * canon * corners.transpose();
            }
            let m = density * vol;
            let centroid = first / vol;
            // Second moment about the centroid, then I = tr(C) 𝟙 − C.
            let c = density * second - m * centroid * centroid.transpose();
            MassProperties {
                mass: m,
                centroid,
                inertia: Matrix3::identity() * c.trace() - c,
            }
        }
        Shape3::Plane => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::super::mesh::{TriMesh, CUBE_OBJ};
    use super::*;

    #[test]
    fn a_shifted_mesh_cube_has_the_box_inertia() {
        let mut m = TriMesh::from_obj(CUBE_OBJ, 1.0).unwrap();
        // Stretch to 2 × 4 × 6 and move it off the origin: the centroid follows, the inertia
        // about it does not change.
        for v in &mut m.vertices {
            *v = V3::new(2.0 * v.x + 0.3, 4.0 * v.y - 1.0, 6.0 * v.z + 2.0);
        }
        let mesh = mass_properties(
            &Shape3::Mesh(TriMesh::new(m.vertices, m.triangles).unwrap()),
            3.0,
        )
        .unwrap();
        let cuboid = mass_properties(
            &Shape3::Box {
                half: [1.0, 2.0, 3.0],
            },
            3.0,
        )
        .unwrap();
        assert!((mesh.mass - 144.0).abs() < 1e-12 && (cuboid.mass - 144.0).abs() < 1e-12);
        assert!((mesh.centroid - V3::new(0.3, -1.0, 2.0)).norm() < 1e-12);
        let err = (mesh.inertia - cuboid.inertia).abs().max();
        assert!(err < 1e-10 * cuboid.inertia.max(), "{err}");
        // 144 (4² + 6²)/12 = 624.
        assert!((cuboid.inertia[(0, 0)] - 624.0).abs() < 1e-12);
    }

    #[test]
    fn sphere_and_ellipsoid_closed_forms() {
        let s = mass_properties(&Shape3::Sphere { radius: 0.04 }, 1000.0).unwrap();
        let e = mass_properties(
            &Shape3::Ellipsoid {
                semi_axes: [0.04; 3],
            },
            1000.0,
        )
        .unwrap();
        assert!((s.mass - e.mass).abs() < 1e-15);
        assert!((s.inertia - e.inertia).abs().max() < 1e-18);
        assert!(mass_properties(&Shape3::Plane, 1.0).is_none());
    }
}
