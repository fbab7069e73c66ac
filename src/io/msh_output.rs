//! Which MSH a mesh artifact is written as: version 4.1 (ASCII or binary)
//! or 2.2 (ASCII), chosen per job with `output` in the parameters.
//!
//! Gmsh, meshio and ParaView read every variant; pyGIMLi and other tools
//! read only 2.2. `atlas.msh` is always 4.1, since `$Parametrizations` exists
//! only there; every other `.msh` artifact follows these options.
//!
//! Unless `msh_binary` says otherwise, MSH 4.1 is binary for models of at
//! least [`AUTO_BINARY_MIN_ELEMENTS`] elements and ASCII below: a small file
//! stays readable in an editor, a large one is about half the bytes and
//! several times faster to write and read (Gmsh reads binary
//! `$Parametrizations` too, so `atlas.msh` follows the same rule).

use std::io::Write;

use serde::{Deserialize, Serialize};

use crate::io::msh22::write::write_msh22;
use crate::io::msh41::model::MshModel;
use crate::io::msh41::write::{Msh41Options, write_msh41};
use crate::io::write_error::WriteError;
use crate::preview::PreviewSize;

/// MSH file format version.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum MshVersion {
    /// MSH 4.1 (`$Entities`, node and element blocks).
    #[default]
    #[serde(rename = "4.1")]
    V41,
    /// MSH 2.2 (flat `$Nodes` / `$Elements`), ASCII.
    #[serde(rename = "2.2")]
    V22,
}

/// Output options of the mesh artifacts (`output` in the parameters).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputOptions {
    /// MSH version of `mesh.msh` and `crossfield.msh`: `"4.1"` (default) or
    /// `"2.2"`. `atlas.msh` is always 4.1.
    pub msh_version: MshVersion,
    /// Write MSH 4.1 in its binary variant (`true`, about 2× smaller, several
    /// times faster to write and read) or ASCII (`false`). Default (absent):
    /// binary from [`AUTO_BINARY_MIN_ELEMENTS`] elements on, ASCII below.
    /// `true` needs `msh_version` 4.1; MSH 2.2 is always ASCII.
    pub msh_binary: Option<bool>,
    /// Draw the preview images (`preview.png` and one per stage). Default `true`.
    pub previews: bool,
    /// Size `[width, height]` of each preview image in pixels, both views
    /// side by side. Default `[1200, 900]`.
    pub preview_size: PreviewSize,
}

impl Default for OutputOptions {
    fn default() -> Self {
        Self {
            msh_version: MshVersion::default(),
            msh_binary: None,
            previews: true,
            preview_size: PreviewSize::default(),
        }
    }
}

/// Element count (all blocks) from which MSH 4.1 is binary by default.
/// Below it an ASCII file is under about 10 MB and written in milliseconds.
pub const AUTO_BINARY_MIN_ELEMENTS: usize = 100_000;

impl OutputOptions {
    /// Checks the combination.
    ///
    /// # Errors
    /// `(field, reason)` when binary output is asked for MSH 2.2.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if self.msh_binary == Some(true) && self.msh_version == MshVersion::V22 {
            return Err(("msh_binary", "binary output is written for MSH 4.1 only; use msh_version \"4.1\"".into()));
        }
        Ok(())
    }

    /// Whether MSH 4.1 output of `model` is binary: `msh_binary` when set,
    /// else whether the model has at least [`AUTO_BINARY_MIN_ELEMENTS`]
    /// elements. (The version is not looked at: `atlas.msh` is 4.1 always.)
    pub fn binary_msh41(&self, model: &MshModel) -> bool {
        self.msh_binary.unwrap_or_else(|| model.n_elements() >= AUTO_BINARY_MIN_ELEMENTS)
    }
}

/// Writes `model` as the MSH variant `opts` selects.
///
/// # Errors
/// [`WriteError`] from the writer of that version.
pub fn write_msh(w: impl Write, model: &MshModel, opts: &OutputOptions) -> Result<(), WriteError> {
    match opts.msh_version {
        MshVersion::V41 => write_msh41(w, model, &Msh41Options { binary: opts.binary_msh41(model) }),
        MshVersion::V22 => write_msh22(w, model),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec3;
    use crate::mesh::{TriMesh, VertexId, fixtures};

    #[test]
    fn each_variant_has_its_header_and_2_2_binary_is_refused() {
        let model = MshModel::from_surface(&fixtures::square(2));
        let head = |o: OutputOptions| {
            let mut v = Vec::new();
            write_msh(&mut v, &model, &o).unwrap();
            String::from_utf8_lossy(&v[..30]).lines().nth(1).unwrap().to_string()
        };
        assert_eq!(head(OutputOptions::default()), "4.1 0 8");
        assert_eq!(head(OutputOptions { msh_binary: Some(true), ..Default::default() }), "4.1 1 8");
        assert_eq!(
            head(OutputOptions { msh_version: MshVersion::V22, msh_binary: Some(false), ..Default::default() }),
            "2.2 0 8"
        );
        assert_eq!(
            head(OutputOptions { msh_version: MshVersion::V22, msh_binary: None, ..Default::default() }),
            "2.2 0 8"
        );
        assert!(
            OutputOptions { msh_version: MshVersion::V22, msh_binary: Some(true), ..Default::default() }
                .validate()
                .is_err()
        );
        assert!(
            OutputOptions { msh_version: MshVersion::V22, msh_binary: Some(false), ..Default::default() }
                .validate()
                .is_ok()
        );
        let o: OutputOptions = serde_json::from_str(r#"{"msh_version": "2.2"}"#).unwrap();
        assert_eq!(o.msh_version, MshVersion::V22);
        assert!(serde_json::from_str::<OutputOptions>(r#"{"msh_version": "3"}"#).is_err());
        let o: OutputOptions = serde_json::from_str(r#"{"msh_binary": false}"#).unwrap();
        assert_eq!(o.msh_binary, Some(false));
    }

    #[test]
    fn binary_by_default_from_the_element_threshold_on() {
        // A strip of `n` triangles: 2 per unit square of a 1 × n/2 grid.
        let strip = |n: usize| {
            let k = n / 2;
            let positions = (0..=k).flat_map(|i| [Vec3::new(i as f64, 0.0, 0.0), Vec3::new(i as f64, 1.0, 0.0)]);
            let triangles = (0..k as u32).flat_map(|i| {
                let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
                [[a, c, b], [b, c, d]].map(|t| t.map(VertexId))
            });
            MshModel::from_surface(&TriMesh { positions: positions.collect(), triangles: triangles.collect() })
        };
        let auto = OutputOptions::default();
        let (below, at) = (strip(AUTO_BINARY_MIN_ELEMENTS - 2), strip(AUTO_BINARY_MIN_ELEMENTS));
        assert_eq!(below.n_elements(), AUTO_BINARY_MIN_ELEMENTS - 2);
        assert!(!auto.binary_msh41(&below));
        assert!(auto.binary_msh41(&at));
        let ascii = OutputOptions { msh_binary: Some(false), ..auto };
        assert!(!ascii.binary_msh41(&at));
        let binary = OutputOptions { msh_binary: Some(true), ..auto };
        assert!(binary.binary_msh41(&below));
        let mut v = Vec::new();
        write_msh(&mut v, &at, &auto).unwrap();
        assert!(v.starts_with(b"$MeshFormat\n4.1 1 8\n"));
        v.clear();
        write_msh(&mut v, &at, &OutputOptions { msh_version: MshVersion::V22, msh_binary: None, ..Default::default() })
            .unwrap();
        assert!(v.starts_with(b"$MeshFormat\n2.2 0 8\n"), "2.2 stays ASCII at every size");
    }
}
