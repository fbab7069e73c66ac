//! Sequences load, repair and the selected stages, writes the artifacts and
//! the report, and reports progress.

pub mod params;

pub use params::{ParamsError, PipelineParams, StageName, parse_params};

/// Media type of an artifact by file extension (`.json`, `.msh`, `.vtu`,
/// `.stl`; anything else is `application/octet-stream`).
pub fn media_type_for(name: &str) -> &'static str {
    match std::path::Path::new(name).extension().and_then(|e| e.to_str()) {
        Some("json") => "application/json",
        Some("msh") => "application/x-gmsh",
        Some("vtu") => "application/vnd.vtk.vtu+xml",
        Some("stl") => "model/stl",
        _ => "application/octet-stream",
    }
}
