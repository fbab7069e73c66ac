//! Draws a stage's preview image and writes it beside the stage's other
//! artifacts. A preview that cannot be drawn (nothing to draw) or written is
//! reported in the job summary ([`PreviewOutcome::error`]) and never fails
//! the job: the stage's real artifacts are already on disk.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::time::Instant;

use crate::io::WriteError;
use crate::io::msh_output::OutputOptions;
use crate::preview::{Image, PreviewError, PreviewSize};

use super::durable::Syncer;
use super::report::PreviewOutcome;

/// The previews a stage drew: their outcomes and the names of the files
/// written.
#[derive(Debug, Clone, Default)]
pub struct Previews {
    /// One outcome per preview tried.
    pub outcomes: Vec<PreviewOutcome>,
    /// Files written (the successful outcomes).
    pub artifacts: Vec<String>,
    /// Wall seconds spent, reported as step `<stage>.preview`.
    pub seconds: f64,
}

impl Previews {
    /// Draws `render` at the size `output` asks for and writes it as
    /// `out_dir/name`, unless previews are off.
    pub fn draw(
        &mut self,
        output: &OutputOptions,
        out_dir: &Path,
        syncer: &Syncer,
        name: &str,
        render: impl FnOnce(PreviewSize) -> Result<Image, PreviewError>,
    ) {
        if !output.previews {
            return;
        }
        let start = Instant::now();
        let written = render(output.preview_size).and_then(|img| write_png(&img, out_dir, syncer, name));
        self.record(out_dir, name, start, written.map_err(|e| e.to_string()));
    }

    /// Writes `out_dir/name` with `write` (a look artifact such as
    /// `surface.glb`, under the same rules as an image), unless previews
    /// are off.
    pub fn write(
        &mut self,
        output: &OutputOptions,
        out_dir: &Path,
        syncer: &Syncer,
        name: &str,
        write: impl FnOnce(&mut BufWriter<File>) -> Result<(), WriteError>,
    ) {
        if !output.previews {
            return;
        }
        let start = Instant::now();
        let path = out_dir.join(name);
        let written = (|| -> Result<(), WriteError> {
            let mut w = BufWriter::new(File::create(&path)?);
            write(&mut w)?;
            let file = w.into_inner().map_err(|e| e.into_error())?;
            Ok(syncer.sync(path.clone(), file)?)
        })();
        self.record(out_dir, name, start, written.map_err(|e| e.to_string()));
    }

    /// Records the outcome of artifact `name`, begun at `start`; a failed
    /// one's partial file is removed (the job lists only what it wrote).
    fn record(&mut self, out_dir: &Path, name: &str, start: Instant, written: Result<(), String>) {
        let seconds = start.elapsed().as_secs_f64();
        self.seconds += seconds;
        let error = match written {
            Ok(()) => {
                self.artifacts.push(name.to_string());
                None
            }
            Err(e) => {
                tracing::warn!(artifact = name, error = %e, "look artifact not written");
                let _ = std::fs::remove_file(out_dir.join(name));
                Some(e)
            }
        };
        self.outcomes.push(PreviewOutcome { name: name.to_string(), seconds, error });
    }
}

/// Writes `img` as `out_dir/name` and hands the file to `syncer`.
fn write_png(img: &Image, out_dir: &Path, syncer: &Syncer, name: &str) -> Result<(), PreviewError> {
    let path = out_dir.join(name);
    let io = |e: std::io::Error| PreviewError::Encode(format!("{}: {e}", path.display()));
    let mut w = BufWriter::new(File::create(&path).map_err(io)?);
    img.write_png(&mut w)?;
    let file = w.into_inner().map_err(|e| io(e.into_error()))?;
    syncer.sync(path.clone(), file).map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_preview_that_cannot_be_drawn_or_written_is_reported_not_raised() {
        let dir = tempfile::tempdir().unwrap();
        let syncer = Syncer::start();
        let output = OutputOptions::default();
        let mut previews = Previews::default();
        previews.draw(&output, dir.path(), &syncer, "empty.png", |_| Err(PreviewError::Empty));
        previews.write(&output, dir.path(), &syncer, "half.glb", |w| {
            std::io::Write::write_all(w, b"glTF")?;
            Err(WriteError::Invalid("stopped half-way".into()))
        });
        let missing = dir.path().join("no-such-dir");
        previews.write(&output, &missing, &syncer, "surface.glb", |_| Ok(()));
        previews.draw(&output, dir.path(), &syncer, "ok.png", |_| {
            Ok(Image { width: 2, height: 1, rgb: vec![0, 0, 0, 255, 255, 255] })
        });
        syncer.finish().unwrap();
        assert_eq!(previews.artifacts, ["ok.png"]);
        let errors: Vec<Option<&str>> = previews.outcomes.iter().map(|o| o.error.as_deref()).collect();
        assert!(errors[0].is_some_and(|e| e.contains("no triangles")), "{errors:?}");
        assert!(errors[1].is_some_and(|e| e.contains("half-way")), "{errors:?}");
        assert!(errors[2].is_some_and(|e| e.contains("No such file")), "{errors:?}");
        assert_eq!(errors[3], None);
        assert!(!dir.path().join("empty.png").exists());
        assert!(!dir.path().join("half.glb").exists(), "a failed artifact leaves no partial file");
        assert!(dir.path().join("ok.png").metadata().unwrap().len() > 8);
    }

    #[test]
    fn previews_off_draws_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let syncer = Syncer::start();
        let output = OutputOptions { previews: false, ..Default::default() };
        let mut previews = Previews::default();
        previews.draw(&output, dir.path(), &syncer, "a.png", |_| panic!("not drawn"));
        previews.write(&output, dir.path(), &syncer, "a.glb", |_| panic!("not written"));
        assert!(previews.outcomes.is_empty() && previews.artifacts.is_empty());
    }
}
