//! Size limits of a 3D world, checked before anything is allocated (issue 34 item 9). The
//! planar rule bounds a rod at 1 000 000 nodes; a 3D node carries 4 unknowns (x, y, z and an
//! edge's twist) and its banded Jacobian about 11 × 4 numbers a row, so the whole gripper is
//! bounded at that many nodes too (4 million unknowns, about 2 GB of factors), a radial
//! gripper at [`MAX_FINGERS`] fingers, and a mesh at [`MAX_MESH_FACES`] triangles (each
//! distance query visits every triangle; above [`WARN_MESH_FACES`] a run is told its cost).

/// Nodes of one prong (the planar per-rod limit).
pub const MAX_PRONG_NODES: usize = 1_000_000;
/// Nodes of all the fingers together.
pub const MAX_TOTAL_NODES: usize = 1_000_000;
/// Fingers of a radial gripper.
pub const MAX_FINGERS: usize = 1_000;
/// Triangles of a mesh (also bounded by the 64 MiB a mesh file may have).
pub const MAX_MESH_FACES: usize = 1_000_000;
/// A mesh with more triangles runs, with a warning of its cost.
pub const WARN_MESH_FACES: usize = 100_000;

/// Which size is over its limit, and the message.
#[derive(Debug, Clone, PartialEq)]
pub enum SizeError {
    Nodes(String),
    Fingers(String),
}

/// Check a gripper of `fingers` prongs of `nodes` nodes each (before building it).
pub fn check_gripper(nodes: usize, fingers: usize) -> Result<(), SizeError> {
    if nodes > MAX_PRONG_NODES {
        return Err(SizeError::Nodes(format!(
            "is too large (at most {MAX_PRONG_NODES} nodes per prong)"
        )));
    }
    if fingers > MAX_FINGERS {
        return Err(SizeError::Fingers(format!(
            "is too large (at most {MAX_FINGERS} fingers)"
        )));
    }
    let total = nodes.saturating_mul(fingers);
    if total > MAX_TOTAL_NODES {
        return Err(SizeError::Nodes(format!(
            "makes {total} nodes over {fingers} fingers (at most {MAX_TOTAL_NODES} in all)"
        )));
    }
    Ok(())
}

/// Check a mesh's triangle count (before its triangles are stored).
pub fn check_mesh_faces(faces: usize) -> Result<(), String> {
    if faces > MAX_MESH_FACES {
        return Err(format!(
            "has {faces} triangles, more than the {MAX_MESH_FACES} a mesh may have \
             (every distance query visits each one): decimate it"
        ));
    }
    Ok(())
}

/// The warning for a mesh of `faces` triangles, if it is large enough to slow a run.
pub fn mesh_cost_warning(faces: usize) -> Option<String> {
    (faces > WARN_MESH_FACES).then(|| {
        format!(
            "the mesh has {faces} triangles: every node's distance query visits each one, \
             about {:.1} s a step for two 10-node fingers (1 M triangles ran at ~1 s a step); \
             a decimated mesh of ~10 000 triangles runs about {:.0}x faster",
            faces as f64 / 1e6,
            faces as f64 / 1e4
        )
    })
}
