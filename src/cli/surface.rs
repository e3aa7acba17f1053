//! `texsyn surface`: texture a mesh by synthesizing directly in its atlas.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use clap::Args;
use texsyn::gpu::synth::{ExtraMap, GpuSynthesizer};
use texsyn::gpu::GpuContext;
use texsyn::surface::atlas::{AtlasOptions, AtlasSource};
use texsyn::surface::gltf_io::{self, MaterialImages};
use texsyn::surface::pipeline::{self, SurfaceOptions};
use texsyn::surface::render::{self, RenderOptions, SurfaceTexture};
use texsyn::surface::seams;
use texsyn::surface::tangent_field::{DirectionSource, ScaleSource, DIRECTION_HELP};
use texsyn::{AnalysisOptions, SynthParams};

use super::synth::{read_source, Magnified, Source};
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
    pub field: DirectionArg,

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

/// A `--field` as given: `constraints:FILE` is read when the command runs (a missing
/// or bad file is a run error, exit 1, like other input files); the rest is parsed now.
#[derive(Clone, Debug)]
pub enum DirectionArg {
    Parsed(DirectionSource),
    Constraints(PathBuf),
}

impl DirectionArg {
    fn load(&self) -> CliResult<DirectionSource> {
        match self {
            DirectionArg::Parsed(d) => Ok(d.clone()),
            DirectionArg::Constraints(path) => Ok(DirectionSource::Constraints(
                texsyn::surface::tangent_field::read_constraints(path)?,
            )),
        }
    }
}

fn parse_direction(s: &str) -> Result<DirectionArg, String> {
    match s.strip_prefix("constraints:").map(str::trim) {
        Some(path) if !path.is_empty() => Ok(DirectionArg::Constraints(PathBuf::from(path))),
        _ => s
            .parse::<DirectionSource>()
            .map(DirectionArg::Parsed)
            .map_err(|e| e.to_string()),
    }
}

/// Refuses an atlas the device cannot synthesize before the mesh work (minutes for
/// large atlases): the synthesis keeps a coordinate pyramid and a Jacobian per texel
/// (16 bytes, about 4/3 of the atlas over all levels) in one buffer, and the texture
/// (times the magnification) must fit the device's texture size.
fn check_atlas_fits(ctx: &GpuContext, atlas: u32, magnify: u32) -> CliResult<()> {
    let limits = ctx.limits();
    let side = atlas as u64 * magnify as u64;
    if side > limits.max_texture_dimension_2d as u64 {
        return Err(fail(format!(
            "--atlas-size {atlas}{}: the atlas texture would be {side} texels a side, the device allows {}; give a smaller --atlas-size",
            if magnify > 1 { format!(" with --magnify {magnify}") } else { String::new() },
            limits.max_texture_dimension_2d
        )));
    }
    let bytes = (atlas as u64).pow(2) * 16 * 4 / 3;
    let max = super::max_buffer_binding(ctx);
    if bytes > max {
        return Err(fail(format!(
            "--atlas-size {atlas}: its synthesis needs about {} MiB in one buffer, the device allows {} MiB; give a smaller --atlas-size (at most about {})",
            bytes >> 20,
            max >> 20,
            (((max * 3 / 4) / 16) as f64).sqrt() as u64
        )));
    }
    Ok(())
}

pub fn run(ui: &Ui, args: SurfaceArgs) -> CliResult<()> {
    check_output_dir(&args.output)?;
    for p in [&args.render, &args.atlas_out].into_iter().flatten() {
        check_output_dir(p)?;
        super::synth::check_save_extension(p)?;
    }
    let outputs: Vec<&std::path::Path> = [
        Some(&args.output),
        args.render.as_ref(),
        args.atlas_out.as_ref(),
    ]
    .into_iter()
    .flatten()
    .map(|p| p.as_path())
    .collect();
    super::check_distinct_outputs(&outputs)?;
    let mut inputs: Vec<(&str, &std::path::Path)> =
        vec![("mesh", &args.mesh), ("exemplar", &args.exemplar)];
    for (what, p) in [
        ("normal map", &args.normal_map),
        ("roughness map", &args.roughness_map),
        ("occlusion map", &args.occlusion_map),
    ] {
        inputs.extend(p.as_deref().map(|p| (what, p)));
    }
    super::check_outputs_not_inputs(&outputs, &inputs)?;
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

    let t = Instant::now();
    let (mut mesh, load) = gltf_io::load_mesh(&args.mesh)?;
    ui.info(format!(
        "mesh: {} ({} vertices, {} triangles, {} primitive(s){}{}{})",
        args.mesh.display(),
        mesh.positions.len(),
        mesh.triangles.len(),
        load.primitives,
        if load.skipped_non_triangle > 0 {
            format!(
                ", {} non-triangle primitive(s) skipped",
                load.skipped_non_triangle
            )
        } else {
            String::new()
        },
        if load.repair.dropped_degenerate > 0 {
            format!(
                ", {} degenerate triangles dropped",
                load.repair.dropped_degenerate
            )
        } else {
            String::new()
        },
        if load.repair.computed_normals {
            ", normals computed"
        } else {
            ""
        },
    ));
    mesh.validate_and_repair()?;
    let load_time = t.elapsed();

    let mut source = read_source(ui, &args.exemplar, None, args.tile.get())?;
    // Material maps, aligned with the exemplar: (normal?, image) in material order.
    let mut material_maps = Vec::new();
    for (path, normal, option) in [
        (&args.normal_map, true, "--normal-map"),
        (&args.roughness_map, false, "--roughness-map"),
        (&args.occlusion_map, false, "--occlusion-map"),
    ] {
        material_maps.push(match path {
            Some(p) => Some((
                ui.load_exemplar(p)
                    .map_err(|e| fail(format!("{option}: {e}")))?,
                normal,
                p.clone(),
            )),
            None => None,
        });
    }
    // Material maps are aligned with the exemplar as given (full resolution with
    // --magnify: they are magnified with the colours).
    let full_size = match &source {
        Source::Image(ex) => Some((ex.width, ex.height)),
        Source::Analysis(_) => None,
    };
    let mut hi_res = None;
    if let Some(f) = args.magnify {
        let (small, hi) = super::synth::magnify_source(source, f)?;
        source = small;
        hi_res = Some(hi);
    }

    let ctx = GpuContext::headless()?;
    ui.info(format!("adapter: {}", ctx.describe()));
    check_atlas_fits(&ctx, args.atlas_size, args.magnify.unwrap_or(1))?;
    let t = Instant::now();
    source.check_fits(&ctx, AnalysisOptions::default().k)?;
    let analysis = match source {
        Source::Analysis(a) => a,
        Source::Image(ex) => {
            let options = AnalysisOptions {
                tileable: args.tile.get(),
                // The atlas synthesis leaves the finest level uncorrected, as `synth`
                // does: its similarity sets would go unread (same bytes without them).
                finest_sets: false,
                ..AnalysisOptions::default()
            };
            texsyn::analysis::analyze(&ex, &options, ui.analysis_progress())?
        }
    };
    let analysis_time = t.elapsed();
    let (map_w, map_h) = match (&hi_res, full_size) {
        (Some(_), Some(size)) => size,
        _ => (analysis.width, analysis.height),
    };
    for (n, _, path) in material_maps.iter().flatten() {
        if (n.width, n.height) != (map_w, map_h) {
            return Err(fail(format!(
                "{} is {}x{}, the exemplar {}x{}: material maps must be aligned with it",
                path.display(),
                n.width,
                n.height,
                map_w,
                map_h
            )));
        }
    }
    let (ex_w, ex_h) = (analysis.width, analysis.height);

    let opts = SurfaceOptions {
        atlas: AtlasOptions {
            source: if args.new_atlas {
                AtlasSource::Generate
            } else if args.keep_uvs {
                AtlasSource::Keep
            } else {
                AtlasSource::Auto
            },
            ..AtlasOptions::for_size(args.atlas_size)
        },
        direction,
        // The texel size counts full-resolution exemplar texels: with --magnify F the
        // synthesis's exemplar texel is F of them.
        scale: args.texel_size.clone().map(|s| {
            let f = args.magnify.unwrap_or(1) as f32;
            match s {
                ScaleSource::Constant(v) => ScaleSource::Constant(v * f),
                ScaleSource::PerVertex(v) => {
                    ScaleSource::PerVertex(v.into_iter().map(|x| x * f).collect())
                }
                ScaleSource::Linear {
                    axis,
                    at_min,
                    at_max,
                } => ScaleSource::Linear {
                    axis,
                    at_min: at_min * f,
                    at_max: at_max * f,
                },
            }
        }),
    };
    ui.progress("preparing the atlas, field and maps...");
    let t = Instant::now();
    let prepared = pipeline::prepare(&mesh, analysis.levels.len(), &opts)?;
    let prepare_time = t.elapsed();
    ui.end_progress();
    ui.info(format!(
        "atlas: {0}x{0}, {1} charts, {2:.0}% covered, {3}",
        prepared.atlas.size,
        prepared.atlas.chart_count,
        prepared.atlas.coverage() * 100.0,
        if prepared.atlas.generated {
            format!("built with xatlas ({})", prepared.atlas.note)
        } else {
            "the mesh's TEXCOORD_0".to_string()
        }
    ));
    if let Some(s) = prepared.texel_size {
        ui.info(format!(
            "texel size: {:.5} world units per exemplar texel",
            s / args.magnify.unwrap_or(1) as f32
        ));
    }
    let sing = prepared.field.singularities().len();
    if sing > 0 {
        ui.info(format!("field: {sing} singular vertices"));
    }
    if prepared.report.clamped > 0 {
        ui.info(format!(
            "note: {} atlas texels ask for more than 8x stretch; clamped",
            prepared.report.clamped
        ));
    }

    let t = Instant::now();
    let synthesizer = GpuSynthesizer::new(&ctx, Arc::new(analysis))?;
    let upload_time = t.elapsed();
    let base = SynthParams {
        seed: args.seed.seed,
        randomness: args.randomness.map(|r| r.0).unwrap_or_default(),
        passes: args.passes,
        coherence: args.coherence,
        ..SynthParams::default()
    };
    let extra: Vec<ExtraMap> = material_maps
        .iter()
        .flatten()
        .map(|(n, normal, _)| ExtraMap {
            // With --magnify: cropped as the exemplar was (to a multiple of the factor).
            pixels: match &hi_res {
                Some(Magnified {
                    width: hw,
                    height: hh,
                    ..
                }) => super::synth::crop_rows(&n.colors, n.width, *hw, *hh),
                None => n.colors.clone(),
            },
            normal: *normal,
            green_down: *normal && args.normal_green_down,
        })
        .collect();
    let t = Instant::now();
    let n = prepared.atlas.size;
    // One synthesis: with --magnify the magnification returns the atlas synthesis too
    // (for the seam figures and the render), with the magnified colours and maps.
    let (synthesis, base_rgba, maps, map_size) = match &hi_res {
        Some(Magnified {
            pixels: hi,
            width: hw,
            height: hh,
            factor: f,
        }) => {
            let params = pipeline::atlas_params(&prepared, &base);
            let m =
                synthesizer.synthesize_magnified_with_maps(&params, hi, *hw, *hh, *f, &extra)?;
            (m.synthesis, m.colors, m.maps, (m.width, m.height))
        }
        None => {
            let (s, maps) = pipeline::synthesize(&synthesizer, &prepared, &base, &extra)?;
            let colors = s.colors.clone();
            (s, colors, maps, (n, n))
        }
    };
    ctx.take_uncaptured_errors()?;
    let synth_time = t.elapsed();
    let seam = seams::seam_report(&prepared.atlas, &synthesis.colors);
    ui.info(format!(
        "seams: {} seam edges, colour step across seams {:.2} vs {:.2} between neighbouring texels (ratio {:.2})",
        seam.seam_edges, seam.seam, seam.interior, seam.ratio
    ));

    // The texture: the atlas itself, or magnified from the full-resolution exemplar.
    let to_image = |w: u32, h: u32, px: Vec<u8>| {
        image::RgbaImage::from_raw(w, h, px).ok_or_else(|| fail("internal: image size mismatch"))
    };
    let base_color = to_image(
        map_size.0,
        map_size.1,
        base_rgba.into_iter().flatten().collect(),
    )?;
    // The synthesized maps, in the order of `material_maps`' present entries.
    let mut synthesized = maps.into_iter();
    let mut next_map =
        |present: bool, pack: fn([u8; 4]) -> [u8; 4]| -> CliResult<Option<image::RgbaImage>> {
            if !present {
                return Ok(None);
            }
            let m = synthesized
                .next()
                .ok_or_else(|| fail("internal: missing material map"))?;
            Ok(Some(to_image(
                map_size.0,
                map_size.1,
                m.into_iter().flat_map(pack).collect(),
            )?))
        };
    // glTF normal textures have green up: a green-down map (rotated in its own
    // convention) has its green flipped.
    let normal = if args.normal_green_down {
        next_map(material_maps[0].is_some(), |p| {
            [p[0], 255 - p[1], p[2], p[3]]
        })?
    } else {
        next_map(material_maps[0].is_some(), |p| p)?
    };
    // glTF packs roughness in green (metallic in blue, 0 here), occlusion in red.
    let metallic_roughness = next_map(material_maps[1].is_some(), |p| [0, p[0], 0, 255])?;
    let occlusion = next_map(material_maps[2].is_some(), |p| [p[0], p[0], p[0], 255])?;

    let t = Instant::now();
    let mut render_image = None;
    if let Some(r) = &args.render {
        let ropts = RenderOptions {
            view_size: args.view_size,
            views: args.views,
            ..RenderOptions::default()
        };
        let coords: Vec<[f32; 2]>;
        let jac: Vec<[f32; 4]>;
        let texture = match &hi_res {
            Some(Magnified {
                pixels: hi,
                width: hw,
                height: hh,
                factor: f,
            }) => {
                // Integer exemplar positions are pixel centres in the synthesis.
                coords = synthesis
                    .coords_f32()
                    .iter()
                    .map(|c| [c[0] + 0.5, c[1] + 0.5])
                    .collect();
                jac = pipeline::jacobians_f32(&prepared);
                SurfaceTexture::Magnified {
                    coords: &coords,
                    jacobian: &jac,
                    width: n,
                    height: n,
                    hi_rgba: bytemuck::cast_slice(hi),
                    hi_width: *hw,
                    hi_height: *hh,
                    factor: *f as f32,
                }
            }
            None => SurfaceTexture::Color {
                rgba: base_color.as_raw(),
                width: base_color.width(),
                height: base_color.height(),
            },
        };
        let img = render::render_views(&ctx, &prepared.atlas.mesh, &texture, &ropts)?;
        render_image = Some((r, img));
    }
    let render_time = t.elapsed();
    // All or nothing: every output is encoded and written to its temporary file before
    // any is renamed over its target (files that existed before stay as they were if
    // any step fails).
    use texsyn::image_io::{encode_image, write_files_atomic};
    let mut files: Vec<(&std::path::Path, Vec<u8>)> = Vec::new();
    if let Some((r, img)) = &render_image {
        files.push((
            r,
            encode_image(r, img.width(), img.height(), 4, img.as_raw())?,
        ));
    }
    if let Some(a) = &args.atlas_out {
        let (w, h) = base_color.dimensions();
        files.push((a, encode_image(a, w, h, 4, base_color.as_raw())?));
    }
    let material = MaterialImages {
        base_color,
        normal,
        metallic_roughness,
        occlusion,
    };
    files.push((
        &args.output,
        gltf_io::encode_glb(&prepared.atlas.mesh, &material)?,
    ));
    write_files_atomic(&files.iter().map(|(p, b)| (*p, &b[..])).collect::<Vec<_>>())?;
    if let Some((r, _)) = &render_image {
        ui.info(format!("render: {}", r.display()));
    }
    if let Some(a) = &args.atlas_out {
        ui.info(format!("atlas image: {}", a.display()));
    }
    ui.info(format!("output: {}", args.output.display()));
    let _ = (ex_w, ex_h);
    ui.info(format!(
        "time: load mesh {}, exemplar analysis {}",
        fmt_duration(load_time),
        fmt_duration(analysis_time)
    ));
    ui.info(format!(
        "      preprocessing {} (atlas {}, field {}, Jacobian + indirection maps {})",
        fmt_duration(prepare_time),
        fmt_duration(prepared.timings.atlas),
        fmt_duration(prepared.timings.field),
        fmt_duration(prepared.timings.maps)
    ));
    ui.info(format!(
        "      GPU upload {}, atlas synthesis + read-back {}, render {}",
        fmt_duration(upload_time),
        fmt_duration(synth_time),
        fmt_duration(render_time)
    ));
    Ok(())
}
