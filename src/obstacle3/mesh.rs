//! A closed triangle mesh (a scanned fruit): read from an OBJ file's text with `tobj`,
//! signed distance by the nearest triangle (Ericson, Real-Time Collision Detection §5.1.5) and
//! the inside/outside sign by the generalized winding number (the sum of the triangles' solid
//! angles, Van Oosterom & Strackee 1983, over 4π: 1 inside, 0 outside), which needs no
//! adjacency and tolerates small cracks. Triangles are expected counter-clockwise seen from
//! outside (outward normals); [`TriMesh::new`] refuses a mesh whose signed volume is not
//! positive.

use super::{Proximity3, V3};

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a over `bytes`, continuing from `h`.
fn fnv1a(bytes: &[u8], mut h: u64) -> u64 {
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

#[derive(Debug, Clone, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<V3>,
    pub triangles: Vec<[usize; 3]>,
    /// Centre and radius of a sphere holding every vertex (the cheap bound).
    pub centre: V3,
    pub radius: f64,
    /// FNV-1a hash of the OBJ text and the scale it was read with (0: not read from a file):
    /// a recording stores it, so that a replay notices a different mesh at the same path.
    pub source_hash: u64,
}

impl TriMesh {
    /// A mesh from vertices and counter-clockwise (outward) triangles.
    pub fn new(vertices: Vec<V3>, triangles: Vec<[usize; 3]>) -> Result<TriMesh, String> {
        crate::rod3d::limits::check_mesh_faces(triangles.len())?;
        if triangles.len() < 4 {
            return Err(format!(
                "a closed mesh needs at least 4 triangles, found {}",
                triangles.len()
            ));
        }
        if let Some(t) = triangles
            .iter()
            .find(|t| t.iter().any(|&i| i >= vertices.len()))
        {
            return Err(format!(
                "triangle {t:?} names a vertex past the {} given",
                vertices.len()
            ));
        }
        let lo = vertices
            .iter()
            .fold(V3::repeat(f64::INFINITY), |a, v| a.inf(v));
        let hi = vertices
            .iter()
            .fold(V3::repeat(f64::NEG_INFINITY), |a, v| a.sup(v));
        let centre = 0.5 * (lo + hi);
        let radius = vertices
            .iter()
            .map(|v| (v - centre).norm())
            .fold(0.0, f64::max);
        let m = TriMesh {
            vertices,
            triangles,
            centre,
            radius,
            source_hash: 0,
        };
        let vol = m.signed_volume();
        if !(vol > 0.0) {
            return Err(format!(
                "the mesh's signed volume is {vol:e}: its triangles must be counter-clockwise seen from outside"
            ));
        }
        Ok(m)
    }

    /// Parse an OBJ file's text (all objects in it, triangulated), scaled by `scale`.
    pub fn from_obj(text: &str, scale: f64) -> Result<TriMesh, String> {
        let opts = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        };
        let mut reader = std::io::BufReader::new(text.as_bytes());
        let (models, _) =
            tobj::load_obj_buf(&mut reader, &opts, |_| Err(tobj::LoadError::OpenFileFailed))
                .map_err(|e| format!("not a readable OBJ mesh: {e}"))?;
        let faces: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
        crate::rod3d::limits::check_mesh_faces(faces)?;
        let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
        for m in &models {
            let base = vertices.len();
            let p = &m.mesh.positions;
            for c in p.chunks_exact(3) {
                let v = V3::new(c[0], c[1], c[2]) * scale;
                if !v.iter().all(|x| x.is_finite()) {
                    return Err(format!(
                        "vertex {} ({}, {}, {}) times scale {scale:e} is not a finite number",
                        vertices.len() + 1,
                        c[0],
                        c[1],
                        c[2]
                    ));
                }
                vertices.push(v);
            }
            for t in m.mesh.indices.chunks_exact(3) {
                triangles.push([
                    base + t[0] as usize,
                    base + t[1] as usize,
                    base + t[2] as usize,
                ]);
            }
        }
        let mut m = TriMesh::new(vertices, triangles)?;
        m.source_hash = fnv1a(text.as_bytes(), fnv1a(&scale.to_le_bytes(), FNV_OFFSET));
        Ok(m)
    }

    #[inline]
    fn corners(&self, t: &[usize; 3]) -> (V3, V3, V3) {
        (
            self.vertices[t[0]],
            self.vertices[t[1]],
            self.vertices[t[2]],
        )
    }

    /// Volume enclosed (divergence theorem: Σ a·(b × c)/6).
    pub fn signed_volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let (a, b, c) = self.corners(t);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Generalized winding number of `p`: ≈ 1 inside, ≈ 0 outside.
    pub fn winding(&self, p: &V3) -> f64 {
        let mut w = 0.0;
        for t in &self.triangles {
            let (a, b, c) = self.corners(t);
            let (a, b, c) = (a - p, b - p, c - p);
            let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
            let num = a.dot(&b.cross(&c));
            let den = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
            w += 2.0 * num.atan2(den);
        }
        w / (4.0 * std::f64::consts::PI)
    }

    /// Signed distance, closest point and outward normal of `p`.
    pub fn query(&self, p: &V3) -> Proximity3 {
        let mut best = (f64::INFINITY, V3::zeros(), 0usize);
        for (k, t) in self.triangles.iter().enumerate() {
            let (a, b, c) = self.corners(t);
            let q = closest_on_triangle(p, &a, &b, &c);
            let d2 = (p - q).norm_squared();
            if d2 < best.0 {
                best = (d2, q, k);
            }
        }
        let (d2, closest, k) = best;
        let inside = self.winding(p) > 0.5;
        let d = d2.sqrt();
        let (a, b, c) = self.corners(&self.triangles[k]);
        let face = (b - a).cross(&(c - a)).normalize();
        let normal = if d > 1e-12 * self.radius {
            let u = (p - closest) / d;
            if inside {
                -u
            } else {
                u
            }
        } else {
            face
        };
        Proximity3 {
            distance: if inside { -d } else { d },
            closest,
            normal,
        }
    }
}

/// The point of triangle abc closest to p (Ericson §5.1.5, by Voronoi regions).
pub fn closest_on_triangle(p: &V3, a: &V3, b: &V3, c: &V3) -> V3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let den = 1.0 / (va + vb + vc);
    a + ab * (vb * den) + ac * (vc * den)
}

/// OBJ text of a unit cube [−½, ½]³ with outward triangles (tests and examples).
pub const CUBE_OBJ: &str = "\
v -0.5 -0.5 -0.5\nv 0.5 -0.5 -0.5\nv 0.5 0.5 -0.5\nv -0.5 0.5 -0.5\n\
v -0.5 -0.5 0.5\nv 0.5 -0.5 0.5\nv 0.5 0.5 0.5\nv -0.5 0.5 0.5\n\
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";

#[cfg(test)]
mod tests {
    use super::super::Shape3;
    use super::*;

    #[test]
    fn an_obj_cube_answers_like_the_box() {
        let m = TriMesh::from_obj(CUBE_OBJ, 2.0).unwrap();
        assert_eq!(m.triangles.len(), 12);
        assert!((m.signed_volume() - 8.0).abs() < 1e-12);
        let b = Shape3::Box { half: [1.0; 3] };
        let mesh = Shape3::Mesh(m);
        for p in [
            V3::new(0.3, 0.2, 0.9),
            V3::new(1.5, 0.2, -0.3),
            V3::new(2.0, 3.0, 0.5),
            V3::new(-0.1, -0.95, 0.2),
            V3::new(1.2, 1.3, 1.4),
        ] {
            let (qm, qb) = (mesh.query(&p), b.query(&p));
            assert!((qm.distance - qb.distance).abs() < 1e-12, "{p:?}");
            assert!((qm.closest - qb.closest).norm() < 1e-12, "{p:?}");
            assert!((qm.normal - qb.normal).norm() < 1e-12, "{p:?}");
            assert!(mesh.lower_bound(&p) <= qm.distance);
        }
    }

    #[test]
    fn inside_out_and_broken_meshes_are_refused() {
        let flipped = CUBE_OBJ.replace("f 1 4 3 2", "f 1 2 3 4");
        // One face flipped keeps a positive signed volume (4/6 of the cube's): the check
        // catches wholly inverted meshes, not single faces.
        let m = TriMesh::from_obj(&flipped, 1.0).unwrap();
        assert!((m.signed_volume() - 2.0 / 3.0).abs() < 1e-12);
        let e = TriMesh::from_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 3 2\n", 1.0).unwrap_err();
        assert!(e.contains("at least 4 triangles"), "{e}");
        let all: String = CUBE_OBJ
            .lines()
            .map(|l| {
                if let Some(f) = l.strip_prefix("f ") {
                    let mut v: Vec<&str> = f.split(' ').collect();
                    v.reverse();
                    format!("f {}\n", v.join(" "))
                } else {
                    format!("{l}\n")
                }
            })
            .collect();
        let e = TriMesh::from_obj(&all, 1.0).unwrap_err();
        assert!(e.contains("counter-clockwise"), "{e}");
        assert!(TriMesh::from_obj("this is not obj", 1.0).is_err());
    }
}
