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
use std::sync::Arc;

use texsyn::analysis::{analyze, AnalysisOptions};
use texsyn::gpu::synth::GpuSynthesizer;
use texsyn::gpu::GpuContext;
use texsyn::surface::atlas::AtlasOptions;
use texsyn::surface::gltf_io::{write_glb, MaterialImages};
use texsyn::surface::pipeline::{self, SurfaceOptions};
use texsyn::surface::render::{render_views, RenderOptions, SurfaceTexture};
use texsyn::surface::seams::seam_report;
use texsyn::surface::tangent_field::DirectionSource;
use texsyn::surface::Mesh;
use texsyn::SynthParams;

fn main() -> texsyn::Result<()> {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    std::fs::create_dir_all(&dir).map_err(|e| texsyn::Error::Write {
        path: dir.clone(),
        reason: format!("cannot create the directory: {e}"),
    })?;
    let exemplar = texsyn::image_io::load_exemplar(
        concat!(env!("CARGO_MANIFEST_DIR"), "/assets/brick.png").as_ref(),
    )?;
    let analysis = Arc::new(analyze(&exemplar, &AnalysisOptions::default(), |_| {})?);
    let ctx = GpuContext::headless()?;
    let synthesizer = GpuSynthesizer::new(&ctx, analysis.clone())?;

    for (name, mesh) in [
        ("sphere", Mesh::uv_sphere(1.0, 48, 24)),
        ("torus", Mesh::torus(1.0, 0.4, 64, 32)),
    ] {
        let mut mesh = mesh;
        mesh.validate_and_repair()?;
        // Atlas (xatlas: these meshes have no uvs), field, Jacobian and indirection maps.
        let options = SurfaceOptions {
            atlas: AtlasOptions::for_size(512),
            direction: DirectionSource::Symmetric {
                n: 2,
                up: glam::Vec3::Y,
                iterations: 200,
            },
            scale: None,
        };
        let prepared = pipeline::prepare(&mesh, analysis.levels.len(), &options)?;
        let params = SynthParams {
            seed: 3,
            ..SynthParams::default()
        };
        let (synthesis, _) = pipeline::synthesize(&synthesizer, &prepared, &params, &[])?;
        let seams = seam_report(&prepared.atlas, &synthesis.colors);
        println!(
            "{name}: {} charts, seam ratio {:.2} ({} seam edges)",
            prepared.atlas.chart_count, seams.ratio, seams.seam_edges
        );
        let rgba: Vec<u8> = synthesis.colors.iter().flatten().copied().collect();
        let n = prepared.atlas.size;
        let base_color = image::RgbaImage::from_raw(n, n, rgba).expect("atlas size");
        let texture = SurfaceTexture::Color {
            rgba: base_color.as_raw(),
            width: n,
            height: n,
        };
        let views = render_views(
            &ctx,
            &prepared.atlas.mesh,
            &texture,
            &RenderOptions::default(),
        )?;
        let png = dir.join(format!("{name}.png"));
        texsyn::image_io::save_image_atomic(
            &png,
            views.width(),
            views.height(),
            4,
            views.as_raw(),
        )?;
        let glb = dir.join(format!("{name}.glb"));
        let material = MaterialImages {
            base_color,
            normal: None,
            metallic_roughness: None,
            occlusion: None,
        };
        write_glb(&glb, &prepared.atlas.mesh, &material)?;
        println!("wrote {} and {}", glb.display(), png.display());
    }
    Ok(())
}
