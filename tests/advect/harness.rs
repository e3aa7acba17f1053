//! The frame loop of the advection tests: an exemplar analysed with its synthesizer
//! ([`Synth`]), an [`Advection`] over it with, optionally, the CPU mirror of its
//! coordinates ([`FrameLoop`]), stepped frame by frame; and the flows the tests use.

use std::sync::Arc;

use texsyn::analysis::{analyze, Analysis, AnalysisOptions, Exemplar};
use texsyn::flow::Flow;
use texsyn::gpu::advect::{AdvectOptions, Advection};
use texsyn::gpu::synth::GpuSynthesizer;
use texsyn::gpu::GpuContext;
use texsyn::passes::plan::SynthPlan;
use texsyn::passes::run_cpu_frame;
use texsyn::passes::velocity::quantize_velocity;
use texsyn::{SynthParams, Synthesis};

use crate::common::{self, ctx};

/// An exemplar, its analysis and a synthesizer on a context (the shared one unless made
/// by [`Synth::gravel_on`]).
pub struct Synth {
    pub exemplar: Exemplar,
    pub analysis: Arc<Analysis>,
    pub synth: Arc<GpuSynthesizer>,
}

impl Synth {
    /// The `size` x `size` crop of the gravel exemplar (its analysis made once per test
    /// binary).
    pub fn gravel(size: u32) -> Self {
        Self::gravel_on(ctx(), size)
    }

    /// [`Synth::gravel`] with its synthesizer on `context` (a test that counts what a
    /// context builds needs one of its own).
    pub fn gravel_on(context: &GpuContext, size: u32) -> Self {
        Self::with_analysis(
            context,
            common::gravel_crop(size),
            common::assets::gravel_crop_analysis(size),
        )
    }

    /// A shipped exemplar, `assets/NAME.png`, whole.
    pub fn asset(name: &str) -> Self {
        let exemplar = common::asset_exemplar(name);
        let analysis = Arc::new(common::assets::analysed(&exemplar));
        Self::with_analysis(ctx(), exemplar, analysis)
    }

    /// `exemplar` analysed with `options` (a feature mask, another weight...).
    pub fn analysed(exemplar: Exemplar, options: &AnalysisOptions) -> Self {
        let analysis = Arc::new(analyze(&exemplar, options, |_| {}).unwrap());
        Self::with_analysis(ctx(), exemplar, analysis)
    }

    fn with_analysis(context: &GpuContext, exemplar: Exemplar, analysis: Arc<Analysis>) -> Self {
        Self {
            synth: Arc::new(GpuSynthesizer::new(context, analysis.clone()).unwrap()),
            exemplar,
            analysis,
        }
    }
}

/// An advection on a context (the shared one unless made by [`FrameLoop::on`]), with
/// the CPU mirror of its coordinates when made by one of the `mirrored` constructors or
/// given one by [`FrameLoop::with_mirror`].
pub struct FrameLoop<'c> {
    pub adv: Advection,
    /// The context the advection lives on.
    pub ctx: &'c GpuContext,
    /// The analysis the frames read (the mirror's, swapped with the synthesizer).
    pub analysis: Arc<Analysis>,
    /// The CPU mirror's coordinate buffer (as long as the GPU's, or longer).
    pub cpu: Option<Vec<[i32; 2]>>,
}

impl FrameLoop<'static> {
    /// Frame 0 of `opts` over `params` on the GPU.
    pub fn new(s: &Synth, params: &SynthParams, opts: AdvectOptions) -> Self {
        FrameLoop::on(ctx(), s, params, opts)
    }

    /// [`FrameLoop::new`] with the CPU mirror, its frame 0 made on the CPU in a buffer as
    /// long as the GPU's.
    pub fn mirrored(s: &Synth, params: &SynthParams, opts: AdvectOptions) -> Self {
        let l = Self::new(s, params, opts);
        let len = l.adv.plan().coord_buffer_len();
        let cpu = cpu_frame0(&l.analysis, l.adv.plan(), &opts, len);
        l.with_mirror(cpu)
    }

    /// [`FrameLoop::new`] with the CPU mirror, its frame 0 made in a buffer with room for
    /// fade state, which the frames may turn on later (the GPU's buffer grows then).
    pub fn mirrored_with_fade_room(s: &Synth, params: &SynthParams, opts: AdvectOptions) -> Self {
        let l = Self::new(s, params, opts);
        let len = l.adv.plan().advect_buffer_len(true);
        let cpu = cpu_frame0(&l.analysis, l.adv.plan(), &opts, len);
        l.with_mirror(cpu)
    }
}

impl<'c> FrameLoop<'c> {
    /// Frame 0 of `opts` over `params` on the GPU of `context` (where `s`'s synthesizer
    /// lives).
    pub fn on(
        context: &'c GpuContext,
        s: &Synth,
        params: &SynthParams,
        opts: AdvectOptions,
    ) -> Self {
        Self {
            adv: Advection::new(s.synth.clone(), params, opts).unwrap(),
            ctx: context,
            analysis: s.analysis.clone(),
            cpu: None,
        }
    }

    /// The loop with `cpu` as its CPU mirror's buffer.
    pub fn with_mirror(mut self, cpu: Vec<[i32; 2]>) -> Self {
        self.cpu = Some(cpu);
        self
    }

    /// The loop with the GPU's current coordinates as its CPU mirror.
    pub fn mirroring_the_gpu(self) -> Self {
        let cpu = self.coords();
        self.with_mirror(cpu)
    }

    /// The plan of the frames.
    pub fn plan(&self) -> SynthPlan {
        self.adv.plan().clone()
    }

    /// The current frame's colours, RGBA8.
    pub fn rgba(&self) -> Vec<u8> {
        self.adv.read_rgba8().unwrap()
    }

    /// The GPU's coordinate buffer.
    pub fn coords(&self) -> Vec<[i32; 2]> {
        self.adv.read_coords().unwrap()
    }

    /// The CPU mirror's buffer.
    pub fn cpu(&self) -> &[[i32; 2]] {
        self.cpu
            .as_deref()
            .expect("a FrameLoop without its CPU mirror")
    }

    /// Whether the GPU's coordinate buffer equals the mirror's.
    pub fn matches_mirror(&self) -> bool {
        self.coords() == self.cpu()
    }

    /// Whether the GPU's coordinate buffer equals the start of the mirror's (which holds
    /// room for fade state the GPU's has not grown yet).
    pub fn matches_mirror_start(&self) -> bool {
        let gpu = self.coords();
        gpu[..] == self.cpu()[..gpu.len()]
    }

    /// New options between frames.
    pub fn set_options(&mut self, opts: AdvectOptions) {
        self.adv.set_options(opts).unwrap();
    }

    /// Swaps in `s`'s synthesizer, and its analysis for the mirror.
    pub fn set_synthesizer(&mut self, s: &Synth) {
        self.adv.set_synthesizer(s.synth.clone()).unwrap();
        self.analysis = s.analysis.clone();
    }

    /// One frame on the GPU under velocities `v` (one per output pixel) and time step
    /// `dt`; the mirror, if any, is left behind.
    pub fn step(&mut self, v: &[[f32; 2]], dt: f32) {
        self.adv.step(v, dt).unwrap();
    }

    /// One frame through a caller-owned velocity buffer holding `v`
    /// (`Advection::encode_step`), submitted at once.
    pub fn step_through_buffer(&mut self, v: &[[f32; 2]], dt: f32) {
        let buffer = velocity_buffer(v);
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        self.adv.encode_step(&mut encoder, &buffer, dt).unwrap();
        self.ctx.queue.submit([encoder.finish()]);
    }

    /// One frame on the GPU and the same frame (the advection's own schedule) on the
    /// mirror: the mirror's output.
    pub fn step_mirrored(&mut self, v: &[[f32; 2]], dt: f32) -> Synthesis {
        self.step_mirrored_with(v, dt, |adv| adv.step(v, dt).unwrap())
    }

    /// [`FrameLoop::step_mirrored`] with the GPU's frame made by `gpu_step` (through a
    /// caller's buffer, options changed while it is recorded...), which must advance it
    /// under `v` and `dt`.
    pub fn step_mirrored_with(
        &mut self,
        v: &[[f32; 2]],
        dt: f32,
        gpu_step: impl FnOnce(&mut Advection),
    ) -> Synthesis {
        // The advection's own schedule: after a change of parameters or analysis it first
        // makes the levels above the advected ones again.
        let schedule = self.adv.frame_schedule();
        gpu_step(&mut self.adv);
        let plan = self.adv.plan();
        let (jac, surface) = (plan.jacobians(), plan.surface_words().0);
        let q: Vec<[i32; 2]> = v.iter().map(|&v| quantize_velocity(v, dt)).collect();
        let analysis = self.analysis.clone();
        let cpu = self
            .cpu
            .as_mut()
            .expect("a FrameLoop without its CPU mirror");
        run_cpu_frame(&analysis, &schedule, cpu, &jac, &surface, &q).unwrap()
    }

    /// Advances the loop by frame `frame` on the GPU and on the mirror; whether their
    /// coordinates agree.
    pub fn step_matches_mirror(&mut self, frame: u64, v: &[[f32; 2]], dt: f32) -> bool {
        assert_eq!(self.adv.frame(), frame);
        self.step_mirrored(v, dt);
        self.matches_mirror()
    }

    /// `frames` frames under the same velocities: `each(t, previous, current)` sees the
    /// colours of frame t - 1 and frame t (t from 1); returns the last frame's colours.
    pub fn run(
        &mut self,
        frames: u64,
        v: &[[f32; 2]],
        dt: f32,
        mut each: impl FnMut(u64, &[u8], &[u8]),
    ) -> Vec<u8> {
        let mut prev = self.rgba();
        for t in 1..=frames {
            self.step(v, dt);
            let cur = self.rgba();
            each(t, &prev, &cur);
            prev = cur;
        }
        prev
    }
}

/// Frame 0 of `plan` with `opts` on the CPU mirror, in a buffer of `len` entries (the
/// advection's coordinate buffer, or longer to hold fade state turned on later).
pub fn cpu_frame0(a: &Analysis, plan: &SynthPlan, opts: &AdvectOptions, len: u64) -> Vec<[i32; 2]> {
    let mut cpu = vec![[0i32; 2]; len as usize];
    run_cpu_frame(
        a,
        &plan.advect_first_schedule(a, opts),
        &mut cpu,
        &plan.jacobians(),
        &plan.surface_words().0,
        &[],
    );
    cpu
}

/// A frame's colours as RGBA8 bytes (as `Advection::read_rgba8` gives them).
pub fn rgba8(s: &Synthesis) -> Vec<u8> {
    s.colors.iter().flatten().copied().collect()
}

/// Synthesis parameters of a `w` x `h` output.
pub fn output(w: u32, h: u32) -> SynthParams {
    SynthParams {
        width: w,
        height: h,
        ..SynthParams::default()
    }
}

/// The velocities of a rigid vortex about the centre of a `w` x `h` output at `omega`
/// radians per frame.
pub fn centred_vortex_velocities(w: u32, h: u32, omega: f32) -> Vec<[f32; 2]> {
    Flow::Vortex {
        cx: 0.5,
        cy: 0.5,
        omega,
    }
    .sample(w, h, 0.0)
    .unwrap()
}

/// Synthesis parameters of a `w` x `h` output and the velocities of a rigid vortex about
/// its centre at `omega` radians per frame.
pub fn centred_vortex(w: u32, h: u32, omega: f32) -> (SynthParams, Vec<[f32; 2]>) {
    (output(w, h), centred_vortex_velocities(w, h, omega))
}

/// The fading tests' flow: a vortex fast enough to renew patches within a few frames.
pub const FAST_VORTEX: Flow = Flow::Vortex {
    cx: 0.5,
    cy: 0.5,
    omega: 0.06,
};

/// Frame `f`'s velocities of `flow` over a `w` x `h` output, and as the GPU quantizes them
/// (dt 1).
pub fn frame_velocities(flow: &Flow, w: u32, h: u32, f: u64) -> (Vec<[f32; 2]>, Vec<[i32; 2]>) {
    let v = flow.sample(w, h, f as f32).unwrap();
    let q = v.iter().map(|&v| quantize_velocity(v, 1.0)).collect();
    (v, q)
}

/// A caller-owned velocity buffer (`Advection::encode_step`) holding `v`.
pub fn velocity_buffer(v: &[[f32; 2]]) -> wgpu::Buffer {
    wgpu::util::DeviceExt::create_buffer_init(
        &ctx().device,
        &wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(v),
            usage: wgpu::BufferUsages::STORAGE,
        },
    )
}
