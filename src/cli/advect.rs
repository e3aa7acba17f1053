//! `texsyn advect`: texture advection frame by frame along a flow, on an image or on a
//! mesh's atlas; frames to a folder or an animation (APNG or GIF), temporal figures on stderr.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Args;
use texsyn::flow::{Flow, FLOW_HELP};
use texsyn::gpu::advect::{AdvectOptions, Advection};
use texsyn::gpu::synth::GpuSynthesizer;
use texsyn::gpu::GpuContext;
use texsyn::quality::FloatImage;
use texsyn::{AnalysisOptions, SynthParams};

use super::bench::print_pass_table;
use super::field::FieldSpec;
use super::frames::{check_animation_fits, write_apng, write_gif, Sink, Staging};
use super::synth::{read_source, Source};
use super::{
    fail, fmt_duration, parse_size, CliResult, TileArgs, Ui, ADVANCED, CONTROLS, LOOK, OUTPUT,
};

/// Advect a synthesized texture along a flow, frame by frame
#[derive(Args, Debug)]
#[command(
    long_about = "Advect a synthesized texture along a flow, frame by frame (paper section 7): \
                  the coordinates of the finest levels move with the flow without resampling, \
                  pixels the flow distorts too much are re-synthesized from the coarser level, \
                  and a correction pass keeps the texture intact (--carry; the default on a mesh \
                  or along a varying --field). In 2D without a field or with a constant one \
                  the default is --keep-look --fade 2, which keeps the texture's look under \
                  turning and divergent flows by remaking it as it moves. Writes the frames to a folder \
                  (frame_00000.png, ...) or an animation (OUT.png: animated PNG; OUT.gif), and prints per-frame cost \
                  and temporal-coherence figures. With --mesh the texture moves over the \
                  surface's atlas (velocities from a 3D flow projected into it) and each frame is \
                  rendered headlessly."
)]
pub struct AdvectArgs {
    /// Exemplar image, or an analysis file written by `texsyn analyze`
    pub exemplar: PathBuf,

    /// The flow (SPEC: see --help)
    #[arg(long, value_name = "SPEC", value_parser = parse_flow, long_help = FLOW_HELP)]
    pub flow: FlowArg,

    /// Output: a folder for PNG frames, or an animation: OUT.png (animated PNG) or OUT.gif
    #[arg(short, long, value_name = "DIR|OUT.png|OUT.gif", value_parser = super::parse_named_output,
          help_heading = OUTPUT)]
    pub output: PathBuf,

    /// Frames to advect after the first
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u32).range(1..=100_000),
          help_heading = OUTPUT)]
    pub frames: u32,

    /// Output size (2D; with --mesh the atlas size is --atlas-size)
    #[arg(long, value_name = "N[xM]", value_parser = parse_size, default_value = "256",
          conflicts_with = "mesh", help_heading = OUTPUT)]
    pub size: [u32; 2],

    /// Write every K-th frame only
    #[arg(long, value_name = "K", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..),
          help_heading = OUTPUT)]
    pub every: u32,

    /// Time step: a frame moves the texture by velocity * dt
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true, help_heading = OUTPUT)]
    pub dt: f64,

    #[command(flatten, next_help_heading = LOOK)]
    pub seed: super::SeedArg,

    /// Keep the texture's look under turning flows by remaking it as it moves (2D default)
    ///
    /// Keep the texture's look under turning and divergent flows: remake the advected
    /// levels below the coarsest one wherever the flow turns or stretches them, and renew
    /// the coarsest where it has turned or stretched by about 5 degrees or 12% (--levels 4
    /// --threshold 0.12, both can still be given), fading what it renews over --fade 2
    /// frames. The texture is continuously remade as it moves; a uniform flow still moves
    /// it exactly. Every advected level is corrected in full every frame, the coarsest
    /// twice where the field is constant (--coarsest-passes). The default in 2D without a
    /// field or with a constant one; on a mesh or along a varying --field it remakes the
    /// detail almost everywhere and pops, and the default there is --carry
    #[arg(long, conflicts_with_all = ["advect_finest", "resynthesize", "carry"], help_heading = LOOK)]
    pub keep_look: bool,

    /// Carry the texture with the flow, the paper's scheme (default on a mesh or a field)
    ///
    /// Carry the texture with the flow (the paper's scheme): the coordinates move with
    /// the flow, only pixels distorted beyond --threshold are renewed, and one correction
    /// pass keeps the texture intact. The default on a mesh or along a varying --field,
    /// where it pops far less than --keep-look; in 2D under a turning flow it breaks the
    /// texture up. Also implied by --advect-finest and --resynthesize
    #[arg(long, help_heading = LOOK)]
    pub carry: bool,

    /// Fade pops in over N frames (0..=64, 0: off) [default: 2 with --keep-look, else 0]
    ///
    /// Fade pops in over N frames (0: off): where a pixel's texture changes other than by
    /// moving with the flow (a renewed patch and the detail remade under it), its old
    /// content moves on with the flow and fades out while the new one fades in, with the
    /// contrast kept. Fewer pops for a slightly higher texture energy; a uniform flow of
    /// whole pixels is unaffected; 0..=64 [default: 2 with --keep-look (the default in 2D
    /// without a varying --field), else 0]
    #[arg(long, value_name = "N", allow_hyphen_values = true,
          value_parser = clap::value_parser!(u32).range(0..=texsyn::passes::advect::MAX_FADE_FRAMES as i64),
          help_heading = LOOK)]
    pub fade: Option<u32>,

    #[command(flatten, next_help_heading = CONTROLS)]
    pub field: super::FieldArg,

    /// Advect over this mesh's atlas instead of an image (.gltf/.glb); frames are renders
    #[arg(long, value_name = "MESH", conflicts_with = "field", help_heading = CONTROLS)]
    pub mesh: Option<PathBuf>,

    /// Atlas size for --mesh (8 to 16384) [default: 512]
    #[arg(long, requires = "mesh",
          value_parser = clap::value_parser!(u32).range(8..=16384), help_heading = CONTROLS)]
    pub atlas_size: Option<u32>,

    #[command(flatten, next_help_heading = CONTROLS)]
    pub tile: TileArgs,

    /// With --fade: the mean colour change (0-255) of the jumps around a pixel that fades
    ///
    /// With --fade: how much the jumps around a pixel that jumped must change the colour
    /// on average (of 255, over its 3x3 neighbourhood) for it to fade (0-255). Lower fades
    /// more pops for a higher texture energy [default: 45]
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u32).range(0..=255),
          allow_hyphen_values = true, help_heading = ADVANCED, hide_short_help = true)]
    pub fade_change: Option<u32>,

    /// Anchored renewals: anchor grid spacing (0: off; 4 works best)
    ///
    /// Anchored renewals (0: off; 4 works best): where the coarsest advected level is
    /// renewed, a pixel continues the nearest-landing of the anchors around it (a grid of
    /// this spacing) straightened along the field, instead of being upsampled from the
    /// coarser level, so it keeps nearly what it showed instead of popping. For textures
    /// without long structures
    #[arg(long, value_name = "SPACING", default_value_t = 0, allow_hyphen_values = true, help_heading = ADVANCED, hide_short_help = true)]
    pub anchor: u32,

    /// With --anchor: the share of the renewals (0-1) upsampled anyway [default: 0.5]
    ///
    /// With --anchor: the share of the renewals (0-1) upsampled from the coarser level
    /// anyway. Anchored renewals never bring back the coarse levels' large structures,
    /// which break up over hundreds of frames without some; lower pops less [default: 0.5]
    #[arg(long, value_name = "SHARE", allow_hyphen_values = true, help_heading = ADVANCED, hide_short_help = true)]
    pub anchor_upsample: Option<f32>,

    /// Levels each frame works on (the finest ones) [default: 3, 4 with --keep-look]
    ///
    /// Levels each frame works on (the finest ones): the finest is upsampled from the
    /// others, which are advected (with --advect-finest, all are advected; with
    /// --resynthesize K, the K below the finest are re-synthesized) [default: 3, 4 with
    /// --keep-look]
    #[arg(long, help_heading = ADVANCED, hide_short_help = true)]
    pub levels: Option<usize>,

    /// Advect and correct the finest level in place too (the paper's scheme)
    ///
    /// Advect and correct the finest level in place too (the paper's scheme) instead of
    /// upsampling it every frame from the advected second-finest level (about twice the
    /// cost per frame, and the texture energy rises more)
    #[arg(long, help_heading = ADVANCED, hide_short_help = true)]
    pub advect_finest: bool,

    /// Levels below the finest that every frame re-synthesizes instead of advecting
    ///
    /// Levels below the finest that every frame re-synthesizes (upsampled from the
    /// advected levels and corrected, as in a synthesis) instead of advecting them: a
    /// turning flow then breaks up only the coarse advected levels, and the texture
    /// keeps its frame-0 energy, for more change between frames; --levels must be at
    /// least this + 2
    #[arg(long, value_name = "K", default_value_t = AdvectOptions::default().resynthesize, help_heading = ADVANCED, hide_short_help = true)]
    pub resynthesize: usize,

    /// Distortion beyond which a pixel is re-synthesized [default: 0.5, 0.12 with --keep-look]
    ///
    /// Distortion threshold |J_obs - J|_F beyond which a pixel is re-synthesized (steps
    /// off by a whole pixel on both sides are patch seams, not distortion, so thresholds
    /// of about 1 and more re-synthesize little: only the pixels with seams on both sides
    /// of both axes, which continue no patch and are re-synthesized at any threshold;
    /// with --keep-look, of the coarsest advected level) [default: 0.5, 0.12 with
    /// --keep-look]
    #[arg(long, help_heading = ADVANCED, hide_short_help = true)]
    pub threshold: Option<f32>,

    /// Correction passes per advected level and frame
    #[arg(long, default_value_t = AdvectOptions::default().passes, help_heading = ADVANCED, hide_short_help = true)]
    pub passes: u32,

    /// Correction passes per frame of the coarsest advected level (0..=16)
    ///
    /// Correction passes per frame of the coarsest advected level (where it is not the
    /// second-finest), 0..=16. With --keep-look a second pass there settles the renewals,
    /// but on a mesh or along a varying --field more passes there pop more [default: with
    /// --keep-look in 2D without a field or with a constant one 2, or --passes if that is
    /// 0 or above 2; else --passes]
    #[arg(long, value_name = "N", help_heading = ADVANCED, hide_short_help = true)]
    pub coarsest_passes: Option<u32>,

    /// Score the similarity sets on every N-th correction only (1..=16) [default: 2, 4 with --keep-look]
    ///
    /// Score the similarity-set candidates on every N-th correction of a pixel on the
    /// most corrected level (the second-finest, the finest with --advect-finest, or the
    /// advected level above the re-synthesized ones with --resynthesize; with
    /// --keep-look, every advected level), 1..=16 (1: every correction); with --passes
    /// above 1, on every N-th pass of a frame [default: 2, 4 with --keep-look]
    #[arg(long, value_name = "N", help_heading = ADVANCED, hide_short_help = true)]
    pub sets_every: Option<u32>,

    /// Interpolate the exemplar bilinearly at the advected coordinates (smoother, softer)
    #[arg(long, help_heading = ADVANCED, hide_short_help = true)]
    pub bilinear: bool,

    /// Score the similarity-set candidates bilinearly (slower, about the same figures)
    #[arg(long, help_heading = ADVANCED, hide_short_help = true)]
    pub interpolate_sets: bool,

    /// Read the exemplar tables exactly, not at the nearest quarter pixel (slower)
    #[arg(long, help_heading = ADVANCED, hide_short_help = true)]
    pub exact_reads: bool,

    /// Also correct the pixels inside coherent patches (slower, about the same figures)
    #[arg(long, help_heading = ADVANCED, hide_short_help = true)]
    pub correct_coherent: bool,

    /// Texture energy every K frames (0: the first and the last only)
    #[arg(long, value_name = "K", default_value_t = 0, help_heading = ADVANCED, hide_short_help = true)]
    pub energy_every: usize,

    /// Also time every dispatch of each frame and print a table per level and pass
    #[arg(long, help_heading = ADVANCED, hide_short_help = true)]
    pub per_pass: bool,
}

/// A `--flow` as given: presets are parsed at once (a typo is a usage error), an
/// `image:FILE` is only read when the command runs, so a missing or bad file is an
/// error of the run (exit 1) like `--field image:FILE`, not a usage error.
#[derive(Clone, Debug)]
pub enum FlowArg {
    Preset(Flow),
    File(PathBuf),
}

impl FlowArg {
    pub fn load(&self) -> CliResult<Flow> {
        match self {
            FlowArg::Preset(flow) => Ok(flow.clone()),
            FlowArg::File(path) => Ok(Flow::load(path)?),
        }
    }
}

pub fn parse_flow(s: &str) -> Result<FlowArg, String> {
    match s.strip_prefix("image:") {
        Some(path) if !path.is_empty() => Ok(FlowArg::File(PathBuf::from(path))),
        _ => s.parse().map(FlowArg::Preset),
    }
}

pub fn run(ui: &Ui, args: AdvectArgs) -> CliResult<()> {
    let dt = super::time_step(args.dt)?;
    let ext = args
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let mut inputs: Vec<(&str, &Path)> = vec![("exemplar", &args.exemplar)];
    if let FlowArg::File(f) = &args.flow {
        inputs.push(("flow file", f));
    }
    inputs.extend(args.mesh.as_deref().map(|m| ("mesh", m)));
    inputs.extend(super::field::FieldSpec::input(&args.field.field));
    super::check_outputs_not_inputs(&[&args.output], &inputs)?;
    let mut staging = None;
    let mut sink = if ext.as_deref() == Some("gif") {
        super::check_output_dir(&args.output)?;
        Sink::Gif(args.output.clone(), Vec::new())
    } else if ext.as_deref() == Some("png") {
        super::check_output_dir(&args.output)?;
        Sink::Apng(args.output.clone(), Vec::new())
    } else if ext.is_some() && !args.output.is_dir() {
        return Err(fail(format!(
            "-o {}: an animation is OUT.png (animated PNG) or OUT.gif; for a folder of frames give a name without an extension (or an existing folder)",
            args.output.display()
        )));
    } else {
        let s = Staging::new(&args.output, &inputs)?;
        let dir = s.dir.clone();
        staging = Some(s);
        Sink::Folder(dir)
    };
    let mut flow = args.flow.load()?;
    if args.mesh.is_some() {
        // On a mesh a vortex or a source turns about the mesh's centre: a centre given in
        // the spec is not used, so it is neither checked nor kept.
        if let Some(c) = flow.centre().filter(|c| *c != [0.5, 0.5]) {
            ui.info(format!(
                "note: the flow's centre {},{} is not used on a mesh (its vortex or source is \
                 centred on the mesh's centre)",
                c[0], c[1]
            ));
            flow = flow.with_centre([0.5, 0.5]);
        }
    }
    flow.validate()?;
    // --keep-look where asked for, and by default where the desired Jacobian is the same
    // everywhere: AdvectOptions::recommended's rule (SynthParams::constant_jacobian), read
    // from the arguments because the options are checked before the analysis and the
    // atlas that the parameters need.
    let constant_j =
        args.mesh.is_none() && matches!(args.field.field, None | Some(FieldSpec::Constant { .. }));
    // An explicit --levels below keep-look's least (3) asks for the texture carried.
    let keep_look = args.keep_look
        || (constant_j
            && !args.carry
            && !args.advect_finest
            && args.resynthesize == 0
            && args.levels.is_none_or(|l| l >= 3));
    let preset = if keep_look {
        AdvectOptions::keep_look()
    } else {
        AdvectOptions::default()
    };
    let options = AdvectOptions {
        levels: args.levels.unwrap_or(preset.levels),
        threshold: args.threshold.unwrap_or(preset.threshold),
        passes: args.passes,
        coarsest_passes: args.coarsest_passes,
        nearest: !args.bilinear,
        interpolate_sets: args.interpolate_sets,
        quarter_reads: !args.exact_reads,
        skip_coherent: !args.correct_coherent,
        sets_every: args.sets_every.unwrap_or(preset.sets_every),
        upsample_finest: !args.advect_finest,
        resynthesize: args.resynthesize,
        keep_look,
        fade: args.fade.unwrap_or(if keep_look {
            texsyn::passes::advect::KEEP_LOOK_FADE
        } else {
            0
        }),
        fade_change: args.fade_change.unwrap_or(preset.fade_change),
        anchor_spacing: args.anchor,
        anchor_upsample: args.anchor_upsample.unwrap_or(preset.anchor_upsample),
    };
    options.check()?;
    // Options that act only with another: said, not silently ignored.
    if args.fade_change.is_some() && options.fade == 0 {
        ui.info("note: --fade-change has no effect without fading (--fade 1 or more)");
    }
    if args.anchor_upsample.is_some() && options.anchor_spacing == 0 {
        ui.info("note: --anchor-upsample has no effect without anchored renewals (--anchor N)");
    }
    // The temporal figures printed at the end use 5x5 windows: refuse what they cannot
    // measure before any frame is written.
    if args.mesh.is_none() && (args.size[0] < 5 || args.size[1] < 5) {
        return Err(fail(format!(
            "--size {}x{}: advection needs an output of at least 5x5 pixels",
            args.size[0], args.size[1]
        )));
    }
    let source = read_source(ui, &args.exemplar, None, args.tile.get())?;
    let ctx = GpuContext::headless()?;
    ui.info(format!("adapter: {}", ctx.describe()));
    ui.info(if keep_look {
        format!(
            "advection: keeping the look, {} (--keep-look{})",
            match options.fade {
                0 => "renewals not faded".to_string(),
                n => format!(
                    "renewals faded over {n} frame{}",
                    if n == 1 { "" } else { "s" }
                ),
            },
            if args.keep_look {
                ""
            } else {
                "; the default here, --carry carries the texture instead"
            }
        )
    } else {
        format!(
            "advection: carrying the texture (the paper's scheme{})",
            if args.carry {
                ", --carry"
            } else if args.advect_finest {
                ", with --advect-finest"
            } else if args.resynthesize > 0 {
                ", with --resynthesize"
            } else if constant_j {
                ", with --levels below 3"
            } else {
                ", the default on a mesh or along a varying field"
            }
        )
    });
    let size_hint = if args.mesh.is_some() {
        "advection keeps the whole atlas in one synthesis: give a smaller --atlas-size"
    } else {
        "advection keeps each whole frame in one synthesis: give a smaller --size"
    };
    if args.mesh.is_none() {
        // Before anything of the output's size is allocated on the host.
        super::check_output_size_hint(&ctx, args.size[0], args.size[1], size_hint)?;
        // A flow image must have the output's size (on a mesh it is refused by the atlas
        // projection): checked before the analysis.
        flow.sample(args.size[0], args.size[1], 0.0)?;
    }
    source.check_fits(&ctx, AnalysisOptions::default().k)?;
    let analysis = match source {
        Source::Analysis(a) => a,
        Source::Image(ex) => {
            let options = AnalysisOptions {
                tileable: args.tile.get(),
                ..AnalysisOptions::default()
            };
            texsyn::analysis::analyze(&ex, &options, ui.analysis_progress())?
        }
    };
    // The temporal figures see what `texsyn eval --flow` sees in the written frames: the
    // colours (grey where the exemplar is grey, so that grey figures stay as they were).
    let grey = analysis.colors.iter().all(|c| c[0] == c[1] && c[1] == c[2]);
    let to_float = move |w: u32, h: u32, rgba: &[[u8; 4]]| -> texsyn::Result<FloatImage> {
        if grey {
            FloatImage::new(w, h, 1, rgba.iter().map(|p| p[0] as f32 / 255.0).collect())
        } else {
            FloatImage::from_rgba8(w, h, rgba)
        }
    };
    let exemplar_image = to_float(analysis.width, analysis.height, &analysis.colors)?;
    let levels = analysis.levels.len();
    let synthesizer = Arc::new(GpuSynthesizer::new(&ctx, Arc::new(analysis))?);

    // 2D output, or a surface: the atlas plus what turns 3D flow into atlas velocities.
    let mut surface = None;
    let mut params = SynthParams {
        width: args.size[0],
        height: args.size[1],
        seed: args.seed.seed,
        ..SynthParams::default()
    };
    if let Some(mesh_path) = &args.mesh {
        let (mut mesh, _) = texsyn::surface::gltf_io::load_mesh(mesh_path)?;
        mesh.validate_and_repair()?;
        let opts = texsyn::surface::pipeline::SurfaceOptions {
            atlas: texsyn::surface::atlas::AtlasOptions::for_size(args.atlas_size.unwrap_or(512)),
            ..Default::default()
        };
        let prepared = texsyn::surface::pipeline::prepare(&mesh, levels, &opts)?;
        params = texsyn::surface::pipeline::atlas_params(&prepared, &params);
        surface = Some(prepared);
    } else if let Some(f) = &args.field.field {
        params.field = Some(f.resolve([0, 0], params.width, params.height)?);
    }
    let (w, h) = (params.width, params.height);

    // The cost of a whole synthesis of the same output, for comparison: a warm-up run
    // (it builds the pipelines), then runs interleaved with the frames (one every
    // FULL_EVERY frames, at least five in all), so that both medians see the same machine
    // (a shared CPU's speed drifts by up to 2x between minutes).
    const FULL_EVERY: u32 = 8;
    // Two: the default synthesis (what a host would run to make each frame from scratch)
    // and a synthesis with the settings of the advection's frame 0 (anisometric, the
    // finest level corrected, no seam blending), whose pyramid a frame updates in part.
    let frame0_params = Advection::synthesis_params(&params);
    let time_synthesis = |p: &SynthParams| -> CliResult<Duration> {
        let t = Instant::now();
        synthesizer
            .synthesize(p)
            .map_err(|e| super::synth::with_hint(e, size_hint))?;
        Ok(t.elapsed())
    };
    let time_full = || -> CliResult<(Duration, Duration)> {
        Ok((time_synthesis(&params)?, time_synthesis(&frame0_params)?))
    };
    time_full()?;
    let mut full = vec![time_full()?];

    let mut adv = Advection::new(synthesizer.clone(), &params, options)
        .map_err(|e| super::synth::with_hint(e, size_hint))?;
    let velocity_at = |t: u32| -> CliResult<Vec<[f32; 2]>> {
        match &surface {
            Some(prep) => Ok(texsyn::surface::flow::atlas_velocity(
                prep, &flow, t as f32,
            )?),
            None => Ok(flow.sample(w, h, t as f32)?),
        }
    };
    // Temporal figures frame by frame (only the previous frame is kept).
    let every = if args.energy_every == 0 {
        usize::MAX
    } else {
        args.energy_every
    };
    let mut figures = texsyn::quality::TemporalFigures::new(&exemplar_image, every);
    // Frames an animation keeps until it is encoded: 0, every, 2 every, ... <= frames.
    let kept_frames = args.frames as u64 / args.every as u64 + 1;
    let mut costs = Vec::new();
    let mut passes = Vec::new();
    // Frames written to the output (every --every-th), and their size (renders with
    // --mesh).
    let mut written = (0u32, [w, h]);
    let mut emit = |adv: &Advection,
                    index: u32,
                    displacement: &[[f32; 2]],
                    figures: &mut texsyn::quality::TemporalFigures|
     -> CliResult<()> {
        let rgba = adv.read_rgba8()?;
        figures.push(
            to_float(w, h, bytemuck::cast_slice::<u8, [u8; 4]>(&rgba))?,
            displacement,
        )?;
        if !index.is_multiple_of(args.every) {
            return Ok(());
        }
        let image = match &surface {
            Some(prep) => {
                let tex = texsyn::surface::render::SurfaceTexture::Color {
                    rgba: &rgba,
                    width: w,
                    height: h,
                };
                texsyn::surface::render::render_views(
                    &ctx,
                    &prep.atlas.mesh,
                    &tex,
                    &texsyn::surface::render::RenderOptions {
                        views: 2,
                        view_size: 256,
                        ..Default::default()
                    },
                )?
            }
            None => image::RgbaImage::from_raw(w, h, rgba).ok_or_else(|| fail("internal: size"))?,
        };
        written = (written.0 + 1, [image.width(), image.height()]);
        match &mut sink {
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
                    check_animation_fits(path, image.width(), image.height(), kept_frames)?;
                }
                list.push(image)
            }
        }
        Ok(())
    };
    emit(&adv, 0, &[], &mut figures)?;
    for t in 1..=args.frames {
        let v = velocity_at(t)?;
        let start = Instant::now();
        if args.per_pass {
            passes.push(adv.profile_step(&v, dt)?);
        } else {
            adv.step(&v, dt)?;
        }
        ctx.wait_idle()?;
        costs.push(start.elapsed());
        emit(&adv, t, &displacement(&v, dt), &mut figures)?;
        if t % FULL_EVERY == 0 {
            full.push(time_full()?);
        }
        ui.progress(format!("frame {t}/{}", args.frames));
    }
    while full.len() < 5 {
        full.push(time_full()?);
    }
    let full_time = median(&mut full.iter().map(|f| f.0).collect::<Vec<_>>());
    let frame0_time = median(&mut full.iter().map(|f| f.1).collect::<Vec<_>>());
    ui.end_progress();
    match &sink {
        Sink::Gif(path, list) => write_gif(path, list)?,
        Sink::Apng(path, list) => write_apng(path, list)?,
        Sink::Folder(_) => {}
    }
    if let Some(s) = staging.take() {
        s.commit()?;
    }
    // A turning flow breaks the texture's patches up over the first tens of frames, and
    // the correction then costs more: the later half of a long run shows the lasting cost.
    let late = (costs.len() >= 16).then(|| {
        let n = costs.len() - costs.len() / 2;
        (n, median(&mut costs[costs.len() / 2..].to_vec()))
    });
    let frame_time = median(&mut costs);
    let report = figures.finish()?;
    ui.info(format!(
        "output: {} ({} frame{} of {}x{})",
        args.output.display(),
        written.0,
        if written.0 == 1 { "" } else { "s" },
        written.1[0],
        written.1[1]
    ));
    ui.info(format!(
        "cost per frame (GPU, synchronized, median{}): {} = {:.0}% of a whole synthesis ({}), \
         {:.0}% of a whole synthesis with the frames' plan ({}: anisometric, finest level \
         corrected, no seam blending)",
        if args.per_pass {
            ", one submission per dispatch"
        } else {
            ""
        },
        fmt_duration(frame_time),
        100.0 * frame_time.as_secs_f64() / full_time.as_secs_f64(),
        fmt_duration(full_time),
        100.0 * frame_time.as_secs_f64() / frame0_time.as_secs_f64(),
        fmt_duration(frame0_time)
    ));
    if let Some((n, late_time)) = late {
        ui.info(format!(
            "  the last {n} frames alone: {} = {:.0}% of a whole synthesis",
            fmt_duration(late_time),
            100.0 * late_time.as_secs_f64() / full_time.as_secs_f64(),
        ));
    }
    if args.per_pass {
        print_pass_table(ui, &passes, "per frame, one submission per dispatch")?;
    }
    let warped = report.mean_warped_diff();
    ui.info(if warped.is_finite() {
        format!(
            "frame-to-frame difference, warped by the flow: {warped:.4} (unwarped {:.4})",
            report.mean_unwarped_diff()
        )
    } else {
        // The figures leave out a 4-pixel border (the flow brings new texture in there).
        let why = if written.1[0] < 9 || written.1[1] < 9 {
            "frames under 9 pixels a side: the measure leaves out a 4-pixel border"
        } else {
            "the flow moves every pixel out of view between frames"
        };
        let unwarped = report.mean_unwarped_diff();
        format!(
            "frame-to-frame difference, warped by the flow: not measurable ({why}){}",
            if unwarped.is_finite() {
                format!("; unwarped {unwarped:.4}")
            } else {
                String::new()
            }
        )
    });
    let pops = report.mean_pops();
    if pops.is_finite() {
        ui.info(format!(
            "popping: {:.2}% of the 8x8 blocks per frame change by more than 0.15 of full \
             scale on average, warped by the flow",
            100.0 * pops
        ));
        // Measured (gravel, vortex, 300 frames): on the bunny's atlas 10.7% with
        // --keep-look against 0.04% without; along a 2D swirl field 3.4% against 0.00%.
        if keep_look && pops > 0.02 && !constant_j {
            ui.info(
                "  --keep-look remakes the fine detail wherever the desired Jacobian changes \
                 along the flow, which on a mesh's atlas or along a varying --field is almost \
                 everywhere: without it (--carry, the default there) the texture is carried \
                 and pops far less (README, Advection)",
            );
        }
    }
    let energies: Vec<String> = report
        .energy
        .iter()
        .map(|(t, e)| format!("frame {t}: {e:.5}"))
        .collect();
    // The last frame's energy over the first's: how much the texture degraded.
    let rise = match (report.energy.first(), report.energy.last()) {
        (Some(&(t0, e0)), Some(&(t1, e1))) if t1 > t0 && e0 > 0.0 => Some(e1 / e0),
        _ => None,
    };
    ui.info(match rise {
        Some(r) => format!(
            "texture energy: {} (last / first: x{r:.2})",
            energies.join(", ")
        ),
        None => format!("texture energy: {}", energies.join(", ")),
    });
    if let Some(r) = rise.filter(|&r| r > 1.2 && !keep_look) {
        ui.info(format!(
            "  the texture energy rose {r:.2}x: the flow breaks the texture up as it turns or \
             stretches it; {} (README, Advection)",
            if constant_j {
                "--keep-look (the default here, unless --carry, --advect-finest, \
                 --resynthesize or --levels below 3 is given) remakes it as it moves and \
                 keeps its look"
            } else {
                "--keep-look remakes it as it moves and keeps its look, but pops on a mesh or \
                 along a varying field"
            }
        ));
    }
    let (first, last) = (
        report.sharpness.first().copied().unwrap_or(f64::NAN),
        report.sharpness.last().copied().unwrap_or(f64::NAN),
    );
    ui.info(if first.is_finite() && last.is_finite() {
        format!("sharpness (high-frequency energy / exemplar's): first {first:.3}, last {last:.3}")
    } else {
        "sharpness: not measurable (the exemplar has no high frequencies to compare with)"
            .to_string()
    });
    Ok(())
}

/// What a frame moves each pixel by: velocity x dt, clamped per component as the
/// advection clamps it ([`texsyn::passes::advect::MAX_SPEED`] pixels a frame).
pub fn displacement(velocity: &[[f32; 2]], dt: f32) -> Vec<[f32; 2]> {
    let m = texsyn::passes::advect::MAX_SPEED;
    velocity
        .iter()
        .map(|p| p.map(|c| (c * dt).clamp(-m, m)))
        .collect()
}

fn median(v: &mut [Duration]) -> Duration {
    v.sort();
    v.get(v.len() / 2).copied().unwrap_or_default()
}
