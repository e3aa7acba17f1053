//! Where `texsyn advect` writes its frames: a folder of PNG frames, filled in a staging
//! folder and swapped in once complete, or an animation (APNG or GIF) kept in memory
//! until it is encoded.

use std::path::{Path, PathBuf};

use super::{fail, CliResult};

/// Frames of a folder output go to a hidden staging folder next to it first; they
/// replace the folder's frames only once every frame was written. A failed run leaves
/// nothing behind (the staging folder is removed when dropped uncommitted), and a
/// shorter re-run leaves no stale frames of an earlier one.
struct Staging {
    dir: PathBuf,
    target: PathBuf,
    committed: bool,
}

fn is_frame_file(name: &str) -> bool {
    name.len() == 15
        && name.starts_with("frame_")
        && name.ends_with(".png")
        && name[6..11].bytes().all(|b| b.is_ascii_digit())
}

impl Staging {
    fn new(target: &Path, inputs: &[(&str, &Path)]) -> CliResult<Self> {
        if target.exists() && !target.is_dir() {
            return Err(fail(format!(
                "{} exists and is not a folder: give a folder for the frames, a .png or a .gif",
                target.display()
            )));
        }
        if std::fs::symlink_metadata(target).is_ok() && !target.exists() {
            return Err(fail(format!(
                "-o {}: a symbolic link to a missing path; remove it or give another folder",
                target.display()
            )));
        }
        if target.is_dir() {
            Self::check_existing(target, inputs)?;
        }
        let name = target.file_name().ok_or_else(|| {
            fail(format!(
                "-o {}: give the frames' folder by name (e.g. -o frames or -o ../frames): \
                     the finished folder replaces it as a whole, which `.` or `..` cannot be",
                target.display()
            ))
        })?;
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        // Like file outputs: the folder itself is created, its parent must exist.
        super::check_parent_dir(target, &parent)?;
        let prefix = format!(".{}.partial-", name.to_string_lossy());
        remove_stale_staging(&parent, &prefix);
        // check_parent_dir listed `target`: an interrupted run removes this folder too
        // (`cli::interrupt::staging_dir` names it the same way).
        let dir = parent.join(format!("{prefix}{}", std::process::id()));
        std::fs::create_dir(&dir).map_err(|e| {
            fail(format!(
                "cannot create the folder {}: {e}",
                target.display()
            ))
        })?;
        Ok(Self {
            dir,
            target: target.to_path_buf(),
            committed: false,
        })
    }

    /// An existing folder takes the frames: checked before any work rather than when
    /// they are moved in. It must take new files, no frame's name may be taken by a
    /// folder, and no input may be one of its frames (this run replaces them).
    fn check_existing(target: &Path, inputs: &[(&str, &Path)]) -> CliResult<()> {
        super::takes_new_files(target).map_err(|e| {
            fail(format!(
                "cannot write the frames into {}: it does not take new files ({e}); choose \
                 a writable folder",
                target.display()
            ))
        })?;
        let entries = std::fs::read_dir(target)
            .map_err(|e| fail(format!("cannot read the folder {}: {e}", target.display())))?;
        for entry in entries.flatten() {
            if is_frame_file(&entry.file_name().to_string_lossy())
                && entry.file_type().is_ok_and(|t| t.is_dir())
            {
                return Err(fail(format!(
                    "cannot write the frames into {}: {} is a folder, where a frame goes; \
                     move it, or give another -o",
                    target.display(),
                    entry.path().display()
                )));
            }
        }
        let folder = std::fs::canonicalize(target).ok();
        for (what, input) in inputs {
            let name = input.file_name().map(|n| n.to_string_lossy().into_owned());
            let parent = match input.parent() {
                Some(p) if !p.as_os_str().is_empty() => p,
                _ => Path::new("."),
            };
            if name.is_some_and(|n| is_frame_file(&n))
                && folder.is_some()
                && std::fs::canonicalize(parent).ok() == folder
            {
                return Err(fail(format!(
                    "the {what} {} is a frame of the output folder {}, which this run \
                     replaces: copy it elsewhere, or give another -o",
                    input.display(),
                    target.display()
                )));
            }
        }
        Ok(())
    }

    fn commit(mut self) -> CliResult<()> {
        let err = |e: std::io::Error| fail(format!("cannot write {}: {e}", self.target.display()));
        if self.target.is_dir() {
            // All or nothing: a name the new frames cannot take (a folder put there
            // since the start) fails before any frame is replaced.
            for entry in std::fs::read_dir(&self.dir).map_err(err)? {
                let to = self.target.join(entry.map_err(err)?.file_name());
                if std::fs::symlink_metadata(&to).is_ok_and(|m| m.is_dir()) {
                    return Err(fail(format!(
                        "cannot write {}: it is a folder, where a frame goes; move it and \
                         run again",
                        to.display()
                    )));
                }
            }
            // The new frames replace the old ones of the same names (each rename is
            // atomic), then the old frames beyond them go: the folder never lacks a
            // frame, and other files in it are kept.
            let mut new = std::collections::HashSet::new();
            for entry in std::fs::read_dir(&self.dir).map_err(err)? {
                let entry = entry.map_err(err)?;
                std::fs::rename(entry.path(), self.target.join(entry.file_name())).map_err(err)?;
                new.insert(entry.file_name());
            }
            for entry in std::fs::read_dir(&self.target).map_err(err)? {
                let entry = entry.map_err(err)?;
                let name = entry.file_name();
                if is_frame_file(&name.to_string_lossy()) && !new.contains(&name) {
                    std::fs::remove_file(entry.path()).map_err(err)?;
                }
            }
            std::fs::remove_dir(&self.dir).map_err(err)?;
        } else {
            std::fs::rename(&self.dir, &self.target).map_err(err)?;
        }
        self.committed = true;
        Ok(())
    }
}

/// Staging folders of runs that were killed (Ctrl-C does not run destructors): those
/// whose process is gone are removed. Only where that can be told (`/proc`, Linux).
fn remove_stale_staging(parent: &Path, prefix: &str) {
    let proc = Path::new("/proc/self");
    if !proc.exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix(prefix))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if !Path::new("/proc").join(pid.to_string()).exists() {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// The frames' destination.
enum Sink {
    /// PNG frames into this (staging) folder.
    Folder(PathBuf),
    /// A GIF at this path, frames kept until the end.
    Gif(PathBuf, Vec<image::RgbaImage>),
    /// An animated PNG at this path, frames kept until the end.
    Apng(PathBuf, Vec<image::RgbaImage>),
}

/// `-o`: a folder of PNG frames (staged, swapped in when complete) or an animation
/// (`.png`: animated PNG, `.gif`), checked before any work.
pub struct FrameOutput {
    sink: Sink,
    staging: Option<Staging>,
    /// Frames an animation keeps until it is encoded.
    kept_frames: u64,
    /// Frames written so far, and their size.
    written: (u32, [u32; 2]),
}

impl FrameOutput {
    /// Checks `output` (and that no input is one of its frames) and prepares it for
    /// `kept_frames` frames.
    pub fn open(output: &Path, inputs: &[(&str, &Path)], kept_frames: u64) -> CliResult<Self> {
        let ext = output
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        let mut staging = None;
        let sink = if ext.as_deref() == Some("gif") {
            super::check_output_dir(output)?;
            Sink::Gif(output.to_path_buf(), Vec::new())
        } else if ext.as_deref() == Some("png") {
            super::check_output_dir(output)?;
            Sink::Apng(output.to_path_buf(), Vec::new())
        } else if ext.is_some() && !output.is_dir() {
            return Err(fail(format!(
                "-o {}: an animation is OUT.png (animated PNG) or OUT.gif; for a folder of frames give a name without an extension (or an existing folder)",
                output.display()
            )));
        } else {
            let s = Staging::new(output, inputs)?;
            let dir = s.dir.clone();
            staging = Some(s);
            Sink::Folder(dir)
        };
        Ok(Self {
            sink,
            staging,
            kept_frames,
            written: (0, [0, 0]),
        })
    }

    /// Writes frame `index` (into the staging folder) or keeps it for the animation.
    pub fn push(&mut self, index: u32, image: image::RgbaImage) -> CliResult<()> {
        self.written = (self.written.0 + 1, [image.width(), image.height()]);
        match &mut self.sink {
            Sink::Folder(dir) => {
                let path = dir.join(format!("frame_{index:05}.png"));
                texsyn::image_io::save_image_atomic(
                    &path,
                    image.width(),
                    image.height(),
                    4,
                    image.as_raw(),
                )?;
            }
            Sink::Gif(path, list) | Sink::Apng(path, list) => {
                if list.is_empty() {
                    check_animation_fits(path, image.width(), image.height(), self.kept_frames)?;
                }
                list.push(image)
            }
        }
        Ok(())
    }

    /// Encodes the animation, or swaps the frames' folder in; the frames written and
    /// their size.
    pub fn finish(mut self) -> CliResult<(u32, [u32; 2])> {
        match &self.sink {
            Sink::Gif(path, list) => write_gif(path, list)?,
            Sink::Apng(path, list) => write_apng(path, list)?,
            Sink::Folder(_) => {}
        }
        if let Some(s) = self.staging.take() {
            s.commit()?;
        }
        Ok(self.written)
    }
}

/// An animated PNG (25 frames per second, looping), written atomically.
fn write_apng(path: &Path, frames: &[image::RgbaImage]) -> CliResult<()> {
    let Some(first) = frames.first() else {
        return Err(fail("no frames to write"));
    };
    let err = |e: png::EncodingError| texsyn::Error::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    texsyn::image_io::write_atomic(path, |w| {
        let mut enc = png::Encoder::new(w, first.width(), first.height());
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_animated(frames.len() as u32, 0).map_err(err)?;
        enc.set_frame_delay(1, 25).map_err(err)?;
        let mut writer = enc.write_header().map_err(err)?;
        for f in frames {
            writer.write_image_data(f.as_raw()).map_err(err)?;
        }
        writer.finish().map_err(err)
    })?;
    Ok(())
}

/// An animation is kept in memory until it is encoded: refuse one that cannot be (GIF
/// sides over 65535 pixels) or that would not fit in the memory available, at its first
/// frame rather than with an allocation failure hundreds of frames later.
fn check_animation_fits(path: &Path, width: u32, height: u32, frames: u64) -> CliResult<()> {
    let gif = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gif"));
    if gif && width.max(height) > 65535 {
        return Err(fail(format!(
            "-o {}: GIF frames are at most 65535 pixels a side and these are {width}x{height}; \
             write an animated PNG (.png) or a folder of frames",
            path.display()
        )));
    }
    let need = frames * width as u64 * height as u64 * 4;
    // Half of what is available: the encoder needs room of its own.
    let have = texsyn::analysis::available_memory().map(|m| m / 2);
    if have.is_some_and(|have| need > have) {
        return Err(fail(format!(
            "-o {}: an animation of {frames} frames of {width}x{height} is kept in memory until \
             it is encoded, about {:.1} GiB, more than this machine has free; write a folder of \
             frames (-o DIR), keep fewer (--every K), or make them smaller",
            path.display(),
            need as f64 / (1u64 << 30) as f64
        )));
    }
    Ok(())
}

/// An animated GIF (25 frames per second, looping), written atomically.
fn write_gif(path: &Path, frames: &[image::RgbaImage]) -> CliResult<()> {
    texsyn::image_io::write_atomic(path, |w| {
        let mut enc = image::codecs::gif::GifEncoder::new_with_speed(w, 10);
        enc.set_repeat(image::codecs::gif::Repeat::Infinite)
            .map_err(|e| texsyn::Error::Write {
                path: path.to_path_buf(),
                reason: e.to_string(),
            })?;
        for f in frames {
            let frame =
                image::Frame::from_parts(f.clone(), 0, 0, image::Delay::from_numer_denom_ms(40, 1));
            enc.encode_frame(frame).map_err(|e| texsyn::Error::Write {
                path: path.to_path_buf(),
                reason: e.to_string(),
            })?;
        }
        Ok(())
    })?;
    Ok(())
}
