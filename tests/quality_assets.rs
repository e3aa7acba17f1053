//! Quality thresholds on the bundled CC0 exemplars: synthesized textures must be far
//! closer to the exemplar than a shuffled-pixel baseline, keep its colour histogram,
//! and copy no large piece of it verbatim.

use texsyn::quality::{self, FloatImage};
use texsyn::Session;

fn check(asset: &str) {
    let path = format!("assets/{asset}.png");
    let ex = texsyn::image_io::load_exemplar(std::path::Path::new(&path)).unwrap();
    let (w, h) = (160, 144);
    let session = Session::builder()
        .exemplar(ex.clone())
        .size(w, h)
        .seed(21)
        .build()
        .unwrap();
    let tex = session.run().unwrap();
    let exf = FloatImage::from_exemplar(&ex);
    let mut out = FloatImage::from_rgba8(w, h, &tex.synthesis.colors).unwrap();
    if ex.channels == 1 {
        out = out.to_grey();
    }
    let energy = quality::texture_energy(&exf, &out, 3).unwrap();
    let shuffled = quality::shuffled_baseline(&exf, w, h, 5);
    let baseline = quality::texture_energy(&exf, &shuffled, 3).unwrap();
    let hist = quality::histogram_distance(&exf, &out).unwrap();
    let v = quality::verbatim_stats(
        tex.coords(),
        w,
        h,
        ex.width,
        ex.height,
        session.analysis().tileable,
    )
    .unwrap();
    eprintln!("{asset}: energy {energy:.5} (shuffled {baseline:.5}), histogram EMD {hist:?}, verbatim {v:?}");
    assert!(
        energy < 0.35 * baseline,
        "{asset}: energy {energy} is not well below the shuffled baseline {baseline}"
    );
    assert!(
        hist.iter().all(|&d| d < 0.03),
        "{asset}: colour histogram drifted: {hist:?}"
    );
    assert!(
        v.largest_region_fraction < 0.3,
        "{asset}: a verbatim copy covers {:.0}% of the exemplar",
        100.0 * v.largest_region_fraction
    );
    assert!(
        v.coherent_fraction > 0.5,
        "{asset}: output is not made of coherent patches ({v:?})"
    );
}

#[test]
fn gravel_quality() {
    check("gravel");
}

#[test]
fn brick_quality() {
    check("brick");
}

#[test]
fn grass_quality() {
    check("grass");
}
