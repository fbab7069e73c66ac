//! Which MSH a mesh artifact is written as: version 4.1 (ASCII or binary)
//! or 2.2 (ASCII), chosen per job with `output` in the parameters.
//!
//! Gmsh, meshio and ParaView read every variant; pyGIMLi and other tools
//! read only 2.2. `atlas.msh` is always 4.1, since `$Parametrizations` exists
//! only there; every other `.msh` artifact follows these options.

use std::io::Write;

use serde::{Deserialize, Serialize};

use crate::io::msh22::write::write_msh22;
use crate::io::msh41::model::MshModel;
use crate::io::msh41::write::{Msh41Options, write_msh41};
use crate::io::write_error::WriteError;

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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputOptions {
    /// MSH version of `mesh.msh` and `crossfield.msh`: `"4.1"` (default) or
    /// `"2.2"`. `atlas.msh` is always 4.1.
    pub msh_version: MshVersion,
    /// Write MSH 4.1 in its binary variant (about 2× smaller, several times
    /// faster to read). Default `false`; needs `msh_version` 4.1.
    pub msh_binary: bool,
}

impl OutputOptions {
    /// Checks the combination.
    ///
    /// # Errors
    /// `(field, reason)` when binary output is asked for MSH 2.2.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if self.msh_binary && self.msh_version == MshVersion::V22 {
            return Err(("msh_binary", "binary output is written for MSH 4.1 only; use msh_version \"4.1\"".into()));
        }
        Ok(())
    }
}

/// Writes `model` as the MSH variant `opts` selects.
///
/// # Errors
/// [`WriteError`] from the writer of that version.
pub fn write_msh(w: impl Write, model: &MshModel, opts: &OutputOptions) -> Result<(), WriteError> {
    match opts.msh_version {
        MshVersion::V41 => write_msh41(w, model, &Msh41Options { binary: opts.msh_binary }),
        MshVersion::V22 => write_msh22(w, model),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn each_variant_has_its_header_and_2_2_binary_is_refused() {
        let model = MshModel::from_surface(&fixtures::square(2));
        let head = |o: OutputOptions| {
            let mut v = Vec::new();
            write_msh(&mut v, &model, &o).unwrap();
            String::from_utf8_lossy(&v[..30]).lines().nth(1).unwrap().to_string()
        };
        assert_eq!(head(OutputOptions::default()), "4.1 0 8");
        assert_eq!(head(OutputOptions { msh_binary: true, ..Default::default() }), "4.1 1 8");
        assert_eq!(head(OutputOptions { msh_version: MshVersion::V22, msh_binary: false }), "2.2 0 8");
        assert!(OutputOptions { msh_version: MshVersion::V22, msh_binary: true }.validate().is_err());
        let o: OutputOptions = serde_json::from_str(r#"{"msh_version": "2.2"}"#).unwrap();
        assert_eq!(o.msh_version, MshVersion::V22);
        assert!(serde_json::from_str::<OutputOptions>(r#"{"msh_version": "3"}"#).is_err());
    }
}
