//! Triangle meshes of the 3D shapes for drawing (the `.rrd` Mesh3D and the MCAP `/scene`
//! triangle lists): a sphere and an ellipsoid as latitude/longitude grids, a box as its six
//! faces (flat normals), a plane as a square of a given half size around its origin, an OBJ mesh
//! as it is. Everything in the shape's own frame; outward counter-clockwise triangles.

use crate::obstacle3::Shape3;

/// Vertices, unit vertex normals and triangles (indices into the vertices).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tessellation {
    pub vertices: Vec<[f64; 3]>,
    pub normals: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// Latitude bands of a sphere (longitudes: twice as many).
pub const BANDS: usize = 16;

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n > 0.0 {
        [v[0] / n, v[1] / n, v[2] / n]
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// An ellipsoid of semi-axes `a` (a sphere when they are equal).
fn ellipsoid(a: [f64; 3]) -> Tessellation {
    let (nlat, nlon) = (BANDS, 2 * BANDS);
    let mut t = Tessellation::default();
    for i in 0..=nlat {
        let phi = std::f64::consts::PI * i as f64 / nlat as f64;
        for j in 0..nlon {
            let lam = 2.0 * std::f64::consts::PI * j as f64 / nlon as f64;
            let s = [phi.sin() * lam.cos(), phi.sin() * lam.sin(), phi.cos()];
            t.vertices.push([a[0] * s[0], a[1] * s[1], a[2] * s[2]]);
            // The gradient of x²/a² + … is the outward normal.
            t.normals
                .push(unit([s[0] / a[0], s[1] / a[1], s[2] / a[2]]));
        }
    }
    let at = |i: usize, j: usize| (i * nlon + j % nlon) as u32;
    for i in 0..nlat {
        for j in 0..nlon {
            let (p, q, r, s) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            if i > 0 {
                t.triangles.push([p, q, s]);
            }
            if i + 1 < nlat {
                t.triangles.push([s, q, r]);
            }
        }
    }
    t
}

fn cuboid(h: [f64; 3]) -> Tessellation {
    let mut t = Tessellation::default();
    for axis in 0..3 {
        for sign in [-1.0, 1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut n = [0.0; 3];
            n[axis] = sign;
            let base = t.vertices.len() as u32;
            for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let mut p = [0.0; 3];
                p[axis] = sign * h[axis];
                p[u] = su * h[u];
                p[v] = sv * h[v];
                t.vertices.push(p);
                t.normals.push(n);
            }
            // (u, v, axis) is right-handed: counter-clockwise in (u, v) faces +axis.
            if sign > 0.0 {
                t.triangles.push([base, base + 1, base + 2]);
                t.triangles.push([base, base + 2, base + 3]);
            } else {
                t.triangles.push([base, base + 2, base + 1]);
                t.triangles.push([base, base + 3, base + 2]);
            }
        }
    }
    t
}

/// The shape's surface; a plane is drawn as a square of half size `plane_half`.
pub fn tessellate(shape: &Shape3, plane_half: f64) -> Tessellation {
    match shape {
        Shape3::Sphere { radius } => ellipsoid([*radius; 3]),
        Shape3::Ellipsoid { semi_axes } => ellipsoid(*semi_axes),
        Shape3::Box { half } => cuboid(*half),
        Shape3::Plane => {
            let l = plane_half;
            Tessellation {
                vertices: vec![[-l, -l, 0.0], [l, -l, 0.0], [l, l, 0.0], [-l, l, 0.0]],
                normals: vec![[0.0, 0.0, 1.0]; 4],
                triangles: vec![[0, 1, 2], [0, 2, 3]],
            }
        }
        Shape3::Mesh(m) => {
            let vertices: Vec<[f64; 3]> = m.vertices.iter().map(|v| (*v).into()).collect();
            let mut normals = vec![[0.0; 3]; vertices.len()];
            for tri in &m.triangles {
                let [a, b, c] = tri.map(|i| m.vertices[i]);
                // Area-weighted face normal onto each corner.
                let n = (b - a).cross(&(c - a));
                for &i in tri {
                    for k in 0..3 {
                        normals[i][k] += n[k];
                    }
                }
            }
            Tessellation {
                vertices,
                normals: normals.into_iter().map(unit).collect(),
                triangles: m.triangles.iter().map(|t| t.map(|i| i as u32)).collect(),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed outward surfaces: the divergence theorem gives the enclosed volume.
    fn volume(t: &Tessellation) -> f64 {
        t.triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|i| nalgebra::Vector3::from(t.vertices[i as usize]));
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn tessellations_enclose_their_volume() {
        let b = tessellate(
            &Shape3::Box {
                half: [1.0, 2.0, 3.0],
            },
            0.0,
        );
        assert!((volume(&b) - 48.0).abs() < 1e-12, "{}", volume(&b));
        let s = tessellate(&Shape3::Sphere { radius: 1.0 }, 0.0);
        let v = volume(&s);
        let exact = 4.0 / 3.0 * std::f64::consts::PI;
        // An inscribed polyhedron: a little less than the sphere, by a few percent at 16 bands.
        assert!(v < exact && v > 0.95 * exact, "{v}");
        let e = tessellate(
            &Shape3::Ellipsoid {
                semi_axes: [1.0, 2.0, 0.5],
            },
            0.0,
        );
        assert!((volume(&e) - v).abs() < 1e-12, "{} vs {v}", volume(&e));
        for n in s.normals.iter().chain(&e.normals) {
            assert!(((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-12);
        }
    }
}
