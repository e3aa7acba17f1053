//! `texsyn advect`: texture advection frame by frame along a flow, on an image or on a
//! mesh's atlas; frames to a folder or an animation (APNG or GIF), temporal figures on stderr.

use std::path::{Path, PathBuf};

use clap::Args;
use texsyn::flow::{Flow, FLOW_HELP};
use texsyn::AdvectOptions;
use texsyn::{AdvectScheme, AdvectSession, DEFAULT_ATLAS_SIZE};

use super::bench::print_pass_table;
use super::field::FieldSpec;
use super::frames::FrameOutput;
use super::{parse_size, CliResult, TileArgs, Ui, ADVANCED, CONTROLS, LOOK, OUTPUT};

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
    let mut inputs: Vec<(&str, &Path)> = vec![("exemplar", &args.exemplar)];
    if let FlowArg::File(f) = &args.flow {
        inputs.push(("flow file", f));
    }
    inputs.extend(args.mesh.as_deref().map(|m| ("mesh", m)));
    inputs.extend(FieldSpec::input(&args.field.field));
    super::check_outputs_not_inputs(&[&args.output], &inputs)?;
    // Frames an animation keeps until it is encoded: 0, every, 2 every, ... <= frames.
    let kept_frames = args.frames as u64 / args.every as u64 + 1;
    let mut output = FrameOutput::open(&args.output, &inputs, kept_frames)?;
    let flow = args.flow.load()?;
    let [width, height] = args.size;
    let field = match &args.field.field {
        Some(f) if args.mesh.is_none() => Some(f.resolve([0, 0], width, height)?),
        _ => None,
    };
    let scheme = AdvectScheme {
        keep_look: args.keep_look,
        carry: args.carry,
        levels: args.levels,
        threshold: args.threshold,
        passes: Some(args.passes),
        coarsest_passes: args.coarsest_passes,
        sets_every: args.sets_every,
        fade: args.fade,
        fade_change: args.fade_change,
        anchor_spacing: args.anchor,
        anchor_upsample: args.anchor_upsample,
        advect_finest: args.advect_finest,
        resynthesize: args.resynthesize,
        bilinear: args.bilinear,
        interpolate_sets: args.interpolate_sets,
        exact_reads: args.exact_reads,
        correct_coherent: args.correct_coherent,
    };
    let mut builder = AdvectSession::builder();
    // SAFETY: nothing in this process writes the file, and texsyn replaces analysis
    // files by renaming a new one over them, which leaves this mapping intact; a one-shot
    // command accepts another program truncating it in place for the faster start.
    builder = unsafe { builder.exemplar_path_mapped(&args.exemplar) };
    if let Some(mesh) = &args.mesh {
        builder = builder
            .mesh_path(mesh)
            .atlas_size(args.atlas_size.unwrap_or(DEFAULT_ATLAS_SIZE));
    }
    let mut session = builder
        .tileable(args.tile.get())
        .size(width, height)
        .flow(flow)
        .dt(dt)
        .field(field)
        .seed(args.seed.seed)
        .scheme(scheme)
        .frames(args.frames)
        .energy_every(args.energy_every)
        .compare_cost(true)
        .profile_passes(args.per_pass)
        .on_progress(ui.analysis_progress())
        .on_note(|note| ui.info(note.to_string()))
        .build()?;
    while let Some(frame) = session.next_frame()? {
        let t = frame.index;
        if t.is_multiple_of(args.every) {
            output.push(t, session.preview(frame)?)?;
        }
        if t > 0 {
            ui.progress(format!("frame {t}/{}", args.frames));
        }
    }
    let summary = session.finish()?;
    ui.end_progress();
    let (written, [w, h]) = output.finish()?;
    ui.info(format!(
        "output: {} ({written} frame{} of {w}x{h})",
        args.output.display(),
        if written == 1 { "" } else { "s" },
    ));
    summary.cost_lines().iter().for_each(|line| ui.info(line));
    if let Some(passes) = &summary.costs.passes {
        print_pass_table(ui, passes, "per frame, one submission per dispatch")?;
    }
    summary.figure_lines().iter().for_each(|line| ui.info(line));
    Ok(())
}
