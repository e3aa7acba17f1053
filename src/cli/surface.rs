//! `texsyn surface`: texture a mesh by synthesizing directly in its atlas.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use texsyn::surface::atlas::AtlasSource;
use texsyn::surface::gltf_io;
use texsyn::surface::render::RenderOptions;
use texsyn::surface::tangent_field::{DirectionSpec, ScaleSource, DIRECTION_HELP};
use texsyn::SynthParams;
use texsyn::{SurfaceEvent, SurfaceMap, SurfaceSession};

use super::synth::{read_source, Source};
use super::{
    check_output_dir, fail, fmt_duration, parse_coherence, parse_randomness, CliResult, Randomness,
    TileArgs, Ui, ADVANCED, CONTROLS, LOOK, OUTPUT,
};

/// Texture a mesh: synthesize in its texture atlas, write a textured .glb
#[derive(Args, Debug)]
#[command(
    long_about = "Texture a mesh (glTF .gltf/.glb) from an exemplar: the texture is synthesized \
                  directly in the mesh's texture atlas (its TEXCOORD_0 when usable, otherwise one \
                  built with xatlas), following a tangent field, seamless across chart edges \
                  through indirection maps. Writes a .glb with the geometry, the atlas uvs and \
                  the texture as its material."
)]
pub struct SurfaceArgs {
    /// Mesh: .gltf (with its buffers) or .glb; every triangle primitive of the scene
    pub mesh: PathBuf,

    /// Exemplar image, or an analysis file written by `texsyn analyze`
    pub exemplar: PathBuf,

    /// Output .glb (written atomically once everything succeeded)
    #[arg(short, long, value_name = "OUT.glb", help_heading = OUTPUT)]
    pub output: PathBuf,

    /// Atlas side in texels (8 to 16384; small meshes need more texels than charts)
    #[arg(long, value_name = "N", default_value_t = 1024,
          value_parser = clap::value_parser!(u32).range(8..=16384), help_heading = OUTPUT)]
    pub atlas_size: u32,

    /// Render the textured mesh from several views into this PNG
    #[arg(long, value_name = "PNG", help_heading = OUTPUT)]
    pub render: Option<PathBuf>,

    /// Views in the render (orbiting the mesh, side by side; 1 to 16)
    #[arg(long, default_value_t = 4, requires = "render",
          value_parser = clap::value_parser!(u32).range(1..=16), help_heading = OUTPUT)]
    pub views: u32,

    /// Size of each rendered view in pixels (16 to 4096)
    #[arg(long, default_value_t = 384, requires = "render",
          value_parser = clap::value_parser!(u32).range(16..=4096), help_heading = OUTPUT)]
    pub view_size: u32,

    /// Also write the raw colour atlas to this image
    #[arg(long, value_name = "PNG", help_heading = OUTPUT)]
    pub atlas_out: Option<PathBuf>,

    #[command(flatten, next_help_heading = LOOK)]
    pub seed: super::SeedArg,

    /// World units per exemplar texel: S, or linear:AX,AY,AZ:S_MIN:S_MAX
    ///
    /// World units per exemplar texel (of the full-resolution exemplar, also with
    /// --magnify): a number, or linear:AX,AY,AZ:S_MIN:S_MAX to vary it along an axis.
    /// Default: one exemplar texel per atlas texel on average
    #[arg(long, value_name = "S|SPEC", value_parser = parse_scale, allow_hyphen_values = true,
          help_heading = LOOK)]
    pub texel_size: Option<ScaleSource>,

    /// Where the exemplar's x axis goes on the surface (SPEC: see --help)
    #[arg(long, value_name = "SPEC", default_value = "up", value_parser = parse_direction,
          long_help = DIRECTION_HELP, help_heading = LOOK)]
    pub field: DirectionSpec,

    /// Magnify 2, 4 or 8 times (the atlas texture is that many times larger)
    ///
    /// Magnify 2, 4 or 8 times: synthesize with a downsampled exemplar and read colours
    /// from the full one (the atlas texture is that many times larger; renders magnify
    /// in the fragment shader)
    #[arg(long, value_name = "F", value_parser = super::synth::parse_magnify, help_heading = LOOK)]
    pub magnify: Option<u32>,

    /// Jitter randomness, one value or one per level, coarsest first (as for synth)
    #[arg(long, value_name = "R|R0,R1,...", value_parser = parse_randomness, help_heading = LOOK)]
    pub randomness: Option<Randomness>,

    /// Tangent-space normal map aligned with the exemplar (green = y up)
    ///
    /// Tangent-space normal map aligned with the exemplar, embedded as the material's
    /// normal texture (rotated with the field). Green is y up (OpenGL, glTF, Blender),
    /// unless --normal-green-down
    #[arg(long, value_name = "IMAGE", help_heading = MATERIAL)]
    pub normal_map: Option<PathBuf>,

    /// The --normal-map has green = y down (DirectX)
    ///
    /// The --normal-map has green = y down (DirectX convention); the embedded texture is
    /// converted to glTF's green up
    #[arg(long, requires = "normal_map", help_heading = MATERIAL)]
    pub normal_green_down: bool,

    /// Roughness map aligned with the exemplar (grey; red channel used)
    ///
    /// Roughness map aligned with the exemplar (grey; red channel used), embedded as the
    /// material's metallic-roughness texture (roughness in green, metallic 0)
    #[arg(long, value_name = "IMAGE", help_heading = MATERIAL)]
    pub roughness_map: Option<PathBuf>,

    /// Ambient-occlusion map aligned with the exemplar (grey; red channel used)
    #[arg(long, value_name = "IMAGE", help_heading = MATERIAL)]
    pub occlusion_map: Option<PathBuf>,

    /// Always build a new atlas (default: keep a usable TEXCOORD_0)
    #[arg(long, conflicts_with = "keep_uvs", help_heading = CONTROLS)]
    pub new_atlas: bool,

    /// Keep the mesh's TEXCOORD_0, or fail if it is not a usable atlas
    #[arg(long, help_heading = CONTROLS)]
    pub keep_uvs: bool,

    #[command(flatten, next_help_heading = CONTROLS)]
    pub tile: TileArgs,

    /// Correction passes on every level but the finest (as for synth)
    #[arg(long, default_value_t = SynthParams::default().passes,
          value_parser = clap::value_parser!(u32).range(0..=16),
          help_heading = ADVANCED, hide_short_help = true)]
    pub passes: u32,

    /// Bias towards coherent candidates in [0, 4] (as for synth)
    #[arg(long, value_name = "C", default_value_t = SynthParams::default().coherence,
          value_parser = parse_coherence, help_heading = ADVANCED, hide_short_help = true)]
    pub coherence: f32,
}

/// Help heading of the material maps embedded in the glTF.
const MATERIAL: &str = "Material maps";

fn parse_scale(s: &str) -> Result<ScaleSource, String> {
    s.parse::<ScaleSource>().map_err(|e| e.to_string())
}

fn parse_direction(s: &str) -> Result<DirectionSpec, String> {
    s.parse::<DirectionSpec>().map_err(|e| e.to_string())
}

/// Refuses bad output paths before any work: a writable folder, an image extension the
/// library writes, no output twice, no output over an input, a .glb for the glTF.
fn check_outputs(args: &SurfaceArgs) -> CliResult<()> {
    check_output_dir(&args.output)?;
    for p in [&args.render, &args.atlas_out].into_iter().flatten() {
        check_output_dir(p)?;
        super::synth::check_save_extension(p)?;
    }
    let outputs: Vec<&Path> = [
        Some(&args.output),
        args.render.as_ref(),
        args.atlas_out.as_ref(),
    ]
    .into_iter()
    .flatten()
    .map(|p| p.as_path())
    .collect();
    super::check_distinct_outputs(&outputs)?;
    let mut inputs: Vec<(&str, &Path)> = vec![("mesh", &args.mesh), ("exemplar", &args.exemplar)];
    for (what, p) in [
        ("normal map", &args.normal_map),
        ("roughness map", &args.roughness_map),
        ("occlusion map", &args.occlusion_map),
    ] {
        inputs.extend(p.as_deref().map(|p| (what, p)));
    }
    super::check_outputs_not_inputs(&outputs, &inputs)?;
    Ok(())
}

pub fn run(ui: &Ui, args: SurfaceArgs) -> CliResult<()> {
    check_outputs(&args)?;
    // A constraints file is read now, before the analysis and the mesh work.
    let direction = args.field.load()?;
    if args.output.extension().and_then(|e| e.to_str()) != Some("glb") {
        return Err(fail(format!(
            "{}: the output is a binary glTF; name it *.glb",
            args.output.display()
        )));
    }
    if args.views == 0 || args.views > 16 || !(16..=4096).contains(&args.view_size) {
        return Err(fail("--views must be 1-16 and --view-size 16-4096"));
    }

    // The inputs, read in this order so that the first bad one is the one reported.
    let t = Instant::now();
    let (mesh, load) = gltf_io::load_mesh(&args.mesh)?;
    let load_time = t.elapsed();
    ui.info(format!(
        "mesh: {} {}",
        args.mesh.display(),
        load.summary(&mesh)
    ));
    let source = read_source(ui, &args.exemplar, None, args.tile.get())?;
    let from_analysis = matches!(source, Source::Analysis(_));
    let mut builder = SurfaceSession::builder().mesh(mesh).exemplar_source(source);
    let load_map = |path: &Option<PathBuf>, option: &str| -> CliResult<Option<SurfaceMap>> {
        let Some(p) = path else { return Ok(None) };
        let image = ui
            .load_exemplar(p)
            .map_err(|e| fail(format!("{option}: {e}")))?;
        Ok(Some(SurfaceMap::new(image, p.display().to_string())))
    };
    if let Some(m) = load_map(&args.normal_map, "--normal-map")? {
        builder = builder.normal_map(m);
    }
    if let Some(m) = load_map(&args.roughness_map, "--roughness-map")? {
        builder = builder.roughness_map(m);
    }
    if let Some(m) = load_map(&args.occlusion_map, "--occlusion-map")? {
        builder = builder.occlusion_map(m);
    }
    if args.magnify.is_some() && from_analysis {
        return Err(fail(
            "--magnify needs the exemplar image (its full-resolution colours), not an analysis file",
        ));
    }

    builder = builder
        .atlas_size(args.atlas_size)
        .atlas_source(match (args.new_atlas, args.keep_uvs) {
            (true, _) => AtlasSource::Generate,
            (_, true) => AtlasSource::Keep,
            _ => AtlasSource::Auto,
        })
        .direction(direction)
        .normal_green_down(args.normal_green_down)
        .seed(args.seed.seed)
        .randomness(args.randomness.map(|r| r.0).unwrap_or_default())
        .passes(args.passes)
        .coherence(args.coherence);
    if let Some(s) = args.texel_size.clone() {
        builder = builder.texel_size(s);
    }
    if let Some(f) = args.magnify {
        builder = builder.magnify(f);
    }
    if let Some(t) = args.tile.get() {
        builder = builder.tileable(t);
    }
    let mut analysis_progress = ui.analysis_progress();
    let session = builder
        .on_progress(move |event| match event {
            SurfaceEvent::Analysis(p) => analysis_progress(p),
            SurfaceEvent::Preparing => ui.progress(event.to_string()),
            _ => ui.info(event.to_string()),
        })
        .build()?;
    let textured = session.run()?;
    ui.info(format!("seams: {}", textured.seams()));

    let t = Instant::now();
    let options = RenderOptions {
        view_size: args.view_size,
        views: args.views,
        ..RenderOptions::default()
    };
    let render = (args.render.as_ref())
        .map(|path| Ok::<_, texsyn::Error>((path, textured.render(&options)?)))
        .transpose()?;
    let render_time = t.elapsed();
    let rendered = render.as_ref().map(|(path, img)| (path.as_path(), img));
    textured.save_all(&args.output, args.atlas_out.as_deref(), rendered)?;
    if let Some((path, _)) = &render {
        ui.info(format!("render: {}", path.display()));
    }
    if let Some(path) = &args.atlas_out {
        ui.info(format!("atlas image: {}", path.display()));
    }
    ui.info(format!("output: {}", args.output.display()));
    let (times, fmt) = (session.timings(), fmt_duration);
    ui.info(format!(
        "time: load mesh {}, exemplar analysis {}\n      preprocessing {} (atlas {}, field {}, \
         Jacobian + indirection maps {})\n      GPU upload {}, atlas synthesis + read-back {}, \
         render {}",
        fmt(load_time),
        fmt(times.analysis),
        fmt(times.prepare),
        fmt(times.prepare_steps.atlas),
        fmt(times.prepare_steps.field),
        fmt(times.prepare_steps.maps),
        fmt(times.upload),
        fmt(textured.synthesis_time()),
        fmt(render_time)
    ));
    Ok(())
}
