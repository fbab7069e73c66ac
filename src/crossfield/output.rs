//! Artifacts of the crossfield stage.
//!
//! `singularities.json`:
//! `{"symmetry": 4, "euler_characteristic": χ, "index_sum": s,
//!   "singularities": [{"position": [x, y, z], "index": 0.25, "vertex": id}, ...]}`
//! with indices as fractions of a full turn (±1/4 crosses, ±1/6 asterisks).

use super::Crossfield;
use serde::Serialize;
use std::io::Write;

#[derive(Serialize)]
struct SingularityJson {
    position: [f64; 3],
    index: f64,
    vertex: u32,
}

#[derive(Serialize)]
struct SingularitiesJson {
    symmetry: u32,
    euler_characteristic: i64,
    index_sum: f64,
    singularities: Vec<SingularityJson>,
}

/// Write `singularities.json` for `field` to `w`.
///
/// # Errors
/// I/O errors of `w`.
pub fn write_singularities_json(field: &Crossfield, w: impl Write) -> std::io::Result<()> {
    let doc = SingularitiesJson {
        symmetry: field.symmetry,
        euler_characteristic: field.euler_characteristic,
        index_sum: field.index_sum,
        singularities: field
            .singularities
            .iter()
            .map(|s| SingularityJson {
                position: [s.position.x, s.position.y, s.position.z],
                index: s.index,
                vertex: s.vertex.0,
            })
            .collect(),
    };
    serde_json::to_writer_pretty(w, &doc).map_err(std::io::Error::other)
}
