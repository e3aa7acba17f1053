//! The bundled exemplars (`assets/`), cropped and analysed as the tests need them.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock};

use texsyn::analysis::{analyze, Analysis, AnalysisOptions, Exemplar};

/// The repository root (the crate's manifest directory).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `assets/NAME` (e.g. `gravel.png`, `meshes/bunny.glb`).
pub fn asset_path(name: &str) -> PathBuf {
    repo().join("assets").join(name)
}

/// A shipped exemplar, `assets/NAME.png`.
pub fn asset_exemplar(name: &str) -> Exemplar {
    let path = asset_path(&format!("{name}.png"));
    texsyn::image_io::load_exemplar(&path)
        .unwrap_or_else(|e| panic!("cannot load {}: {e}", path.display()))
}

/// The bundled gravel exemplar (128x128).
pub fn gravel() -> Exemplar {
    asset_exemplar("gravel")
}

/// The top-left `size` x `size` crop of the gravel exemplar (small exemplars keep GPU
/// tests fast).
pub fn gravel_crop(size: u32) -> Exemplar {
    gravel_crop_rect(size, size)
}

/// The top-left `w` x `h` crop of the gravel exemplar.
pub fn gravel_crop_rect(w: u32, h: u32) -> Exemplar {
    let full = gravel();
    let c = full.channels as usize;
    let (mut values, mut colors) = (Vec::new(), Vec::new());
    for y in 0..h as usize {
        for x in 0..w as usize {
            let i = y * full.width as usize + x;
            values.extend_from_slice(&full.values[i * c..(i + 1) * c]);
            colors.push(full.colors[i]);
        }
    }
    Exemplar {
        width: w,
        height: h,
        channels: full.channels,
        values,
        colors,
    }
}

/// `ex` analysed with the default options.
pub fn analysed(ex: &Exemplar) -> Analysis {
    analyze(ex, &AnalysisOptions::default(), |_| {}).unwrap()
}

/// The default analysis of the `size` x `size` gravel crop, made once per test binary.
pub fn gravel_crop_analysis(size: u32) -> Arc<Analysis> {
    type Cache = Mutex<Vec<(u32, Arc<Analysis>)>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let mut c = CACHE.get_or_init(Default::default).lock().unwrap();
    if let Some((_, a)) = c.iter().find(|(s, _)| *s == size) {
        return a.clone();
    }
    let a = Arc::new(analysed(&gravel_crop(size)));
    c.push((size, a.clone()));
    a
}
