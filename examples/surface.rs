//! Surface synthesis through the library: texture a generated sphere (with poles) and a
//! torus with the bundled brick exemplar following a 2-fold symmetric (relaxed) field, write
//! textured .glb files and render them headlessly.
//!
//! ```text
//! cargo run --release --example surface [OUT_DIR]      # default: the current directory
//! ```
//!
//! OUT_DIR is created if it does not exist.

use std::path::PathBuf;

use texsyn::analysis::{analyze, AnalysisOptions};
use texsyn::surface::render::RenderOptions;
use texsyn::surface::tangent_field::DirectionSource;
use texsyn::surface::Mesh;
use texsyn::GpuContext;
use texsyn::SurfaceSession;

fn main() -> texsyn::Result<()> {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    std::fs::create_dir_all(&dir).map_err(|e| texsyn::Error::Write {
        path: dir.clone(),
        reason: format!("cannot create the directory: {e}"),
    })?;
    // One analysis and one device for both meshes.
    let exemplar = texsyn::image_io::load_exemplar(
        concat!(env!("CARGO_MANIFEST_DIR"), "/assets/brick.png").as_ref(),
    )?;
    let analysis = analyze(&exemplar, &AnalysisOptions::default(), |_| {})?;
    let ctx = GpuContext::headless()?;

    for (name, mesh) in [
        ("sphere", Mesh::uv_sphere(1.0, 48, 24)),
        ("torus", Mesh::torus(1.0, 0.4, 64, 32)),
    ] {
        // Atlas (xatlas: these meshes have no uvs), field, Jacobian and indirection maps.
        let session = SurfaceSession::builder()
            .mesh(mesh)
            .analysis(analysis.clone())
            .context(ctx.clone())
            .atlas_size(512)
            .direction(DirectionSource::Symmetric {
                n: 2,
                up: glam::Vec3::Y,
                iterations: 200,
            })
            .seed(3)
            .build()?;
        let textured = session.run()?;
        let seams = textured.seams();
        println!(
            "{name}: {} charts, seam ratio {:.2} ({} seam edges)",
            session.prepared().atlas.chart_count,
            seams.ratio,
            seams.seam_edges
        );
        let views = textured.render(&RenderOptions::default())?;
        let png = dir.join(format!("{name}.png"));
        let glb = dir.join(format!("{name}.glb"));
        textured.save_all(&glb, None, Some((&png, &views)))?;
        println!("wrote {} and {}", glb.display(), png.display());
    }
    Ok(())
}
