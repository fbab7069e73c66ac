//! Stage 1, the atlas (thesis chapter 2): feature edges and curves, disk-like
//! patches, one-to-one mean value parameterization of each patch.
//!
//! [`build_atlas`] runs the stage; the modules are its steps: [`features`]
//! (§4.1), [`creases`] (model faces cut along the creases inside them), [`curvature`] (Rusinkiewicz 2004), [`patch`] and [`partition`]
//! (§4.2, disk topology and METIS bisection), [`refine`] (§5.1 longest-edge
//! bisection), [`mvc`] (§3.3–3.4 mean value coordinates), [`verify`] (§3
//! injectivity, §2 σ2/σ1).

pub mod build;
pub mod creases;
pub mod curvature;
pub mod error;
pub mod features;
pub mod mvc;
pub mod options;
pub mod output;
pub mod partition;
pub mod patch;
pub mod refine;
pub mod report;
pub mod verify;

pub use build::{Atlas, AtlasCurve, AtlasPatch, build_atlas};
pub use error::AtlasError;
pub use options::AtlasOptions;
pub use output::{write_atlas_msh, write_atlas_msh_as, write_atlas_uv_vtu, write_atlas_vtu};
pub use report::AtlasReport;
