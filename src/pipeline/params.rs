//! Pipeline parameters: which stages to run and each stage's options.
//!
//! Parameters arrive as JSON (an HTTP `params` part or query parameter, or
//! the CLI's `--params FILE.json`). Unknown fields are rejected everywhere,
//! and the error names the offending field with its path (`load.wobble`),
//! so a typo never silently falls back to a default.

use serde::{Deserialize, Serialize};

use crate::atlas::{AtlasError, AtlasOptions};
use crate::crossfield::{CrossfieldError, CrossfieldOptions, validate_options};
use crate::frames::{FramesError, FramesOptions};
use crate::io::msh_output::OutputOptions;
use crate::io::{IoError, LoadOptions};
use crate::quads::{QuadsError, QuadsOptions};

/// Parameters of one pipeline run.
///
/// Adding a stage adds one [`StageName`] variant and one options field here.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PipelineParams {
    /// Stages to run after load and repair, in pipeline order whatever the
    /// order given. Default: none (load, repair and write the mesh only).
    pub stages: Vec<StageName>,
    /// Reading and repair: weld tolerance (relative to the bounding-box
    /// diagonal, default 1e-6) and triangle cap (default 5e6).
    pub load: LoadOptions,
    /// Options of the atlas stage (also the feature angle used by the
    /// crossfield's alignment constraints).
    pub atlas: AtlasOptions,
    /// Options of the crossfield stage.
    pub crossfield: CrossfieldOptions,
    /// Options of the frames stage.
    pub frames: FramesOptions,
    /// Options of the quads stage.
    pub quads: QuadsOptions,
    /// How the mesh artifacts are written (MSH version, binary).
    pub output: OutputOptions,
}

/// A computation stage that can follow load and repair; stages run in this
/// order whatever order they are requested in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum StageName {
    /// Feature curves, disk-like patches, mean value maps (thesis ch. 2).
    Atlas,
    /// Ginzburg–Landau crossfield and its singularities (thesis ch. 3).
    Crossfield,
    /// Volume mesh and smooth 3D frame field with its singular edges (thesis ch. 4).
    Frames,
    /// All-quadrilateral surface mesh aligned with the crossfield (needs
    /// the atlas and the crossfield, run first when not requested).
    Quads,
}

impl StageName {
    /// Stages this build can run, in pipeline order.
    pub const ALL: &'static [StageName] =
        &[StageName::Atlas, StageName::Crossfield, StageName::Frames, StageName::Quads];

    /// The lowercase name used in JSON, reports and progress.
    pub fn as_str(self) -> &'static str {
        match self {
            StageName::Atlas => "atlas",
            StageName::Crossfield => "crossfield",
            StageName::Frames => "frames",
            StageName::Quads => "quads",
        }
    }

    /// Stages whose products this stage reads (they run before it).
    pub fn dependencies(self) -> &'static [StageName] {
        match self {
            StageName::Quads => &[StageName::Atlas, StageName::Crossfield],
            StageName::Atlas | StageName::Crossfield | StageName::Frames => &[],
        }
    }

    /// The stage called `name`.
    ///
    /// # Errors
    /// A message saying whether the name is unknown or not built yet.
    pub fn parse(name: &str) -> Result<Self, String> {
        if let Some(s) = Self::ALL.iter().find(|s| s.as_str() == name) {
            return Ok(*s);
        }
        let available = Self::ALL.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(", ");
        Err(format!("unknown stage `{name}` (available stages: {available})"))
    }
}

impl Serialize for StageName {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for StageName {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        StageName::parse(&name).map_err(serde::de::Error::custom)
    }
}

impl PipelineParams {
    /// The stages to run, in pipeline order without repeats, with the
    /// dependencies of the requested ones ([`StageName::dependencies`]), and
    /// the dependencies that were added because they were not requested.
    pub fn stages_to_run(&self) -> (Vec<StageName>, Vec<StageName>) {
        let mut run: Vec<StageName> = self.stages.clone();
        let mut added: Vec<StageName> = Vec::new();
        for s in &self.stages {
            for d in s.dependencies() {
                if !run.contains(d) {
                    run.push(*d);
                    added.push(*d);
                }
            }
        }
        run.sort();
        run.dedup();
        added.sort();
        (run, added)
    }
}

/// Parameters that do not deserialize.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct ParamsError {
    /// Path of the offending field (`stages[0]`, `load.wobble`), when known.
    pub field: Option<String>,
    /// What is wrong, as serde reports it.
    pub message: String,
    /// True when the text is not JSON at all (as opposed to JSON that does
    /// not fit the schema).
    pub syntax: bool,
}

/// Extracts the name from serde's "unknown field `x`, expected …" message.
fn unknown_field_name(message: &str) -> Option<&str> {
    let rest = message.strip_prefix("unknown field `")?;
    rest.split('`').next()
}

/// serde_json's message without its " at line L column C" suffix.
fn serde_message(e: &serde_json::Error) -> String {
    let full = e.to_string();
    match full.rfind(" at line ") {
        Some(k) if e.line() > 0 => full[..k].to_string(),
        _ => full,
    }
}

/// Rejects JSON text whose top-level value is not an object.
///
/// serde's derived `Deserialize` also accepts a struct written as a sequence
/// of its fields (`[["crossfield"]]` would set `stages`), which the API's
/// schema (`type: object`) does not allow. Text that is no JSON at all is a
/// syntax error.
fn require_object(json: &[u8]) -> Result<(), ParamsError> {
    let first = json.iter().find(|b| !matches!(b, b' ' | b'\t' | b'\n' | b'\r'));
    if first == Some(&b'{') {
        return Ok(());
    }
    let got = match serde_json::from_slice::<serde_json::Value>(json) {
        Ok(serde_json::Value::Array(_)) => "an array",
        Ok(serde_json::Value::Number(_)) => "a number",
        Ok(serde_json::Value::String(_)) => "a string",
        Ok(serde_json::Value::Bool(_)) => "a boolean",
        Ok(serde_json::Value::Null) => "null",
        Ok(serde_json::Value::Object(_)) => return Ok(()),
        Err(e) => return Err(ParamsError { field: None, message: serde_message(&e), syntax: true }),
    };
    Err(ParamsError { field: None, message: format!("parameters must be a JSON object, got {got}"), syntax: false })
}

/// Parses pipeline parameters from JSON, naming the offending field on error.
///
/// # Errors
/// [`ParamsError`] for malformed JSON, a top-level value that is not an
/// object, unknown fields, wrong types or unknown stages.
pub fn parse_params(json: &[u8]) -> Result<PipelineParams, ParamsError> {
    require_object(json)?;
    let mut de = serde_json::Deserializer::from_slice(json);
    let parsed: Result<PipelineParams, _> = serde_path_to_error::deserialize(&mut de);
    let params = parsed.map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner();
        let syntax = inner.is_syntax() || inner.is_eof();
        let message = serde_message(&inner);
        let field = match unknown_field_name(&message) {
            Some(name) if path == "." || path.is_empty() => Some(name.to_string()),
            Some(name) if !path.ends_with(name) => Some(format!("{path}.{name}")),
            _ if path == "." || path.is_empty() || syntax => None,
            _ => Some(path),
        };
        ParamsError { field, message, syntax }
    })?;
    de.end().map_err(|e| ParamsError { field: None, message: e.to_string(), syntax: true })?;
    params.load.validate().map_err(|e| match e {
        IoError::InvalidOptions { option, reason } => {
            ParamsError { field: Some(format!("load.{option}")), message: reason, syntax: false }
        }
        other => ParamsError { field: Some("load".into()), message: other.to_string(), syntax: false },
    })?;
    params.atlas.validate().map_err(|e| match e {
        AtlasError::InvalidOption { name, reason } => {
            ParamsError { field: Some(format!("atlas.{name}")), message: reason, syntax: false }
        }
        other => ParamsError { field: Some("atlas".into()), message: other.to_string(), syntax: false },
    })?;
    validate_options(&params.crossfield).map_err(|e| match e {
        CrossfieldError::InvalidOption { name, reason } => {
            ParamsError { field: Some(format!("crossfield.{name}")), message: reason, syntax: false }
        }
        other => ParamsError { field: Some("crossfield".into()), message: other.to_string(), syntax: false },
    })?;
    params.frames.validate().map_err(|e| match e {
        FramesError::InvalidOption { name, reason } => {
            ParamsError { field: Some(format!("frames.{name}")), message: reason, syntax: false }
        }
        other => ParamsError { field: Some("frames".into()), message: other.to_string(), syntax: false },
    })?;
    params.quads.validate().map_err(|e| match e {
        QuadsError::InvalidOption { name, reason } => {
            ParamsError { field: Some(format!("quads.{name}")), message: reason, syntax: false }
        }
        other => ParamsError { field: Some("quads".into()), message: other.to_string(), syntax: false },
    })?;
    params.output.validate().map_err(|(name, reason)| ParamsError {
        field: Some(format!("output.{name}")),
        message: reason,
        syntax: false,
    })?;
    Ok(params)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_object_gives_defaults() {
        let json = |p: PipelineParams| serde_json::to_value(p).unwrap();
        assert_eq!(json(parse_params(b"{}").unwrap()), json(PipelineParams::default()));
        assert_eq!(json(parse_params(b" {\"stages\": []} ").unwrap()), json(PipelineParams::default()));
        let p = parse_params(br#"{"load": {"max_triangles": 7}}"#).unwrap();
        assert_eq!((p.load.max_triangles, p.load.weld_tolerance), (7, 1e-6));
    }

    #[test]
    fn only_a_json_object_is_accepted() {
        for (json, got) in [
            (&b"[[\"crossfield\"]]"[..], "an array"),
            (b" [] ", "an array"),
            (b"1", "a number"),
            (b"\"x\"", "a string"),
            (b"null", "null"),
            (b"true", "a boolean"),
        ] {
            let e = parse_params(json).unwrap_err();
            assert_eq!(e.message, format!("parameters must be a JSON object, got {got}"), "{e:?}");
            assert!(!e.syntax && e.field.is_none(), "{e:?}");
        }
        assert!(parse_params(b"[\"crossfield\"").unwrap_err().syntax);
        assert!(parse_params(b"").unwrap_err().syntax);
        assert!(parse_params(b"\n\t{}").is_ok());
    }

    #[test]
    fn nested_unknown_fields_and_bad_ranges_are_named() {
        let e = parse_params(br#"{"load": {"wobble": 1}}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("load.wobble"), "{e:?}");
        let e = parse_params(br#"{"load": {"weld_tolerance": 0.5}}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("load.weld_tolerance"), "{e:?}");
        assert!(!e.syntax);
        let e = parse_params(br#"{"load": {"max_triangles": -3}}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("load.max_triangles"), "{e:?}");
    }

    #[test]
    fn unknown_fields_are_named() {
        let e = parse_params(br#"{"stages": [], "wobble": 1}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("wobble"), "{e:?}");
        assert!(e.message.contains("unknown field `wobble`"), "{e:?}");
        assert!(!e.syntax);
    }

    #[test]
    fn every_stage_parses_and_unknown_stages_are_explained() {
        let p = parse_params(br#"{"stages": ["frames", "atlas", "crossfield"]}"#).unwrap();
        assert_eq!(p.stages, vec![StageName::Frames, StageName::Atlas, StageName::Crossfield]);
        let e = parse_params(br#"{"stages": ["atlas", "bogus"]}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("stages[1]"), "{e:?}");
        assert!(
            e.message.contains("unknown stage `bogus` (available stages: atlas, crossfield, frames, quads)"),
            "{e:?}"
        );
        for s in StageName::ALL {
            assert_eq!(StageName::parse(s.as_str()), Ok(*s));
        }
    }

    #[test]
    fn quads_add_the_atlas_and_the_crossfield_when_not_requested() {
        let p = parse_params(br#"{"stages": ["quads"]}"#).unwrap();
        assert_eq!(
            p.stages_to_run(),
            (
                vec![StageName::Atlas, StageName::Crossfield, StageName::Quads],
                vec![StageName::Atlas, StageName::Crossfield]
            )
        );
        let p = parse_params(br#"{"stages": ["quads", "crossfield", "frames"]}"#).unwrap();
        let all = vec![StageName::Atlas, StageName::Crossfield, StageName::Frames, StageName::Quads];
        assert_eq!(p.stages_to_run(), (all, vec![StageName::Atlas]));
        let p = parse_params(br#"{"stages": ["crossfield", "crossfield"]}"#).unwrap();
        assert_eq!(p.stages_to_run(), (vec![StageName::Crossfield], vec![]));
    }

    #[test]
    fn quads_options_are_checked_and_unknown_ones_named() {
        let e = parse_params(br#"{"quads": {"order": 3}}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("quads.order"), "{e:?}");
        let e = parse_params(br#"{"quads": {"sise": 1}}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("quads.sise"), "{e:?}");
        let p = parse_params(br#"{"quads": {"size": 0.5, "order": 2, "smoothing_iterations": 3}}"#).unwrap();
        assert_eq!((p.quads.size, p.quads.order, p.quads.smoothing_iterations), (Some(0.5), 2, 3));
    }

    #[test]
    fn malformed_json_is_a_syntax_error() {
        let e = parse_params(b"{\"stages\": [").unwrap_err();
        assert!(e.syntax && e.field.is_none(), "{e:?}");
        let e = parse_params(b"{} trailing").unwrap_err();
        assert!(e.syntax, "{e:?}");
        let e = parse_params(br#"{"stages": 3}"#).unwrap_err();
        assert!(!e.syntax && e.field.as_deref() == Some("stages"), "{e:?}");
    }
}
