//! The builder API end to end: analyse a bundled exemplar, synthesize a 256x256 texture
//! on a headless GPU (lavapipe when there is no GPU) and save it.
//!
//! ```text
//! cargo run --release --example basic [OUT.png]      # default: out.png
//! ```

use texsyn::Session;

fn main() -> texsyn::Result<()> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "out.png".to_string());
    let exemplar = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/gravel.png");

    // Analysis (CPU) + device creation + upload; the analysis could also come from a
    // file written by `texsyn analyze` (`.exemplar_path("gravel.tsa")` reads either).
    let session = Session::builder()
        .exemplar_path(exemplar)
        .seed(7)
        .size(256, 256)
        .build()?;
    println!("adapter: {}", session.context().describe());

    // Synthesize and read the pixels back to the host.
    let texture = session.run()?;
    texture.save(&out)?;
    println!("wrote {out} ({}x{})", texture.width(), texture.height());

    // Same exemplar, other parameters: another seed, a non-square window.
    let params = texsyn::SynthParams {
        seed: 8,
        width: 320,
        height: 200,
        ..session.params().clone()
    };
    let other = session.run_with(&params)?;
    println!(
        "seed 8: {}x{}, {} RGBA8 bytes",
        other.width(),
        other.height(),
        other.rgba8().len()
    );
    Ok(())
}
