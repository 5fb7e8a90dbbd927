//! The renderer: pipelines and per-size targets of one frame, drawn from a published particle set
//! (`sim::frame::FrameBuffers`) and the boundary objects' poses. Pass order:
//!
//! 1. `scene`: opaque tools and walls, tissue impostors (and blood as plain spheres when fluid
//!    rendering is off), translucent walls — into an HDR colour texture and the depth buffer;
//! 2. `blood thickness`: additive chord lengths of the blood spheres, depth-tested against the scene;
//! 3. `blood depth`: the blood's front-surface eye depth (depth-tested, writes the depth buffer);
//! 4. `filter h`, `filter v`: separable bilateral smoothing of that depth;
//! 5. `composite`: normals from the filtered depth, Beer–Lambert absorption over the thickness,
//!    refraction of the scene behind, Fresnel reflection — into the caller's target (window surface
//!    or offscreen texture), over which the viewer then draws egui.
//!
//! `Renderer` is long-lived (pipelines, layouts); the size-dependent textures are rebuilt on resize.

use super::camera::OrbitCamera;
use super::gpu_data::{CameraGpu, FieldMode, ShapeGpu};
use crate::scenario::Region;
use crate::sim::ObjectPose;
use crate::sim::frame::FrameBuffers;
use crate::sim::gpu::shaders::shader_source;
use glam::Vec3;
use std::collections::HashMap;

const SCENE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const FLUID_DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
const THICKNESS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Float;

/// How a frame looks (all safe to change every frame).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub field: FieldMode,
    /// Full scale of the colour map for `field`.
    pub field_scale: f32,
    /// Screen-space fluid rendering of blood (off: lit spheres).
    pub fluid: bool,
    /// Impostor radii as multiples of half the particle spacing.
    pub tissue_radius: f32,
    pub blood_radius: f32,
    /// Beer–Lambert absorption coefficient [1/m] (scaled per channel in the shader).
    pub absorption: f32,
    /// Largest bilateral filter radius \[px\].
    pub filter_radius_px: f32,
    /// Draw the boundary objects that are not tools (walls, plates).
    pub show_walls: bool,
    pub background: [f32; 3],
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            field: FieldMode::Plain,
            field_scale: FieldMode::Plain.default_scale(),
            fluid: true,
            tissue_radius: 1.1,
            blood_radius: 1.3,
            absorption: 1000.0,
            filter_radius_px: 20.0,
            show_walls: true,
            background: [0.08, 0.09, 0.11],
        }
    }
}

/// What to draw: a published particle set (bind group from [`Renderer::bind_frame`]) and the objects.
pub struct Scene<'a> {
    pub particles: Option<(&'a wgpu::BindGroup, u32, u32)>,
    pub objects: &'a [ObjectPose],
    /// Simulation coordinates = scenario coordinates − origin.
    pub origin: [f64; 3],
    /// Particle spacings Δx of the solid and of the liquid \[m\].
    pub dx_solid: f32,
    pub dx_liquid: f32,
}

/// Radius of a moulded bed's balls over Δx_s: neighbours on its lattice overlap into one surface.
const BED_BALL: f32 = 0.6;
/// Linear RGBA of a moulded bed (the abdominal organs under the liver: pale, pinkish grey).
const BED_COLOUR: [f32; 4] = [0.36, 0.27, 0.26, 1.0];

/// Why the renderer could not be built or could not draw.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    #[error("renderer shader `{name}`: {message}")]
    Shader { name: String, message: String },
    #[error("render target {width}×{height} is not drawable (limit {limit} px per side)")]
    BadSize { width: u32, height: u32, limit: u32 },
}

/// A scalpel drawn as a tool rather than as its collision box: the box (the simulated blade) as a
/// steel wedge whose cutting edge is the bottom of its height axis (scenarios have "up" along +y or
/// +z), and a dark handle on its spine — drawn only, not simulated. Axes from the box's extents:
/// thickness the smallest, length the largest, height the other.
fn scalpel_shapes(a: [f32; 4], b: [f32; 4]) -> (ShapeGpu, Option<ShapeGpu>) {
    let ext = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let by = |cmp: fn(f32, f32) -> bool| (0..3).fold(0, |k, i| if cmp(ext[i], ext[k]) { i } else { k });
    let (t, l) = (by(|x, y| x < y), by(|x, y| x > y));
    let steel = [0.78, 0.8, 0.84, 1.0];
    if t == l {
        // a cube: no blade to speak of
        return (ShapeGpu { a, b, colour: steel, kind: [0; 4] }, None);
    }
    let h = 3 - t - l;
    let blade = ShapeGpu { a, b, colour: steel, kind: [2, t as u32, h as u32, 0] };
    let (mut ha, mut hb) = (a, b);
    let mid = 0.5 * (a[t] + b[t]);
    (ha[t], hb[t]) = (mid - 1.5 * ext[t], mid + 1.5 * ext[t]);
    (ha[h], hb[h]) = (b[h], b[h] + 0.6 * ext[h]);
    (ha[l], hb[l]) = (a[l] + 0.05 * ext[l], b[l] - 0.05 * ext[l]);
    let handle = ShapeGpu { a: ha, b: hb, colour: [0.07, 0.08, 0.09, 1.0], kind: [0; 4] };
    (blade, Some(handle))
}

/// Size-dependent textures and their bind groups.
struct Targets {
    size: (u32, u32),
    scene: wgpu::TextureView,
    depth: wgpu::TextureView,
    fluid_a: wgpu::TextureView,
    fluid_b: wgpu::TextureView,
    thickness: wgpu::TextureView,
    /// The textures behind `fluid_a` and `thickness` (read back by tests).
    fluid_a_tex: wgpu::Texture,
    thickness_tex: wgpu::Texture,
    /// Fluid bind groups: filter h reads A, filter v reads B, composite reads A.
    read_a: wgpu::BindGroup,
    read_b: wgpu::BindGroup,
}

pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    camera_buf: wgpu::Buffer,
    camera_group: wgpu::BindGroup,
    particle_layout: wgpu::BindGroupLayout,
    shape_layout: wgpu::BindGroupLayout,
    fluid_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    tissue: wgpu::RenderPipeline,
    blood_plain: wgpu::RenderPipeline,
    blood_thickness: wgpu::RenderPipeline,
    blood_depth: wgpu::RenderPipeline,
    shapes_opaque: wgpu::RenderPipeline,
    shapes_translucent: wgpu::RenderPipeline,
    filter_h: wgpu::RenderPipeline,
    filter_v: wgpu::RenderPipeline,
    fluid_module: wgpu::ShaderModule,
    fluid_pipeline_layout: wgpu::PipelineLayout,
    composite: HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>,
    shape_buf: wgpu::Buffer,
    shape_capacity: u64,
    shape_group: wgpu::BindGroup,
    targets: Option<Targets>,
    pub settings: RenderSettings,
    /// GPU time per pass (timestamp queries), where the device has them.
    timer: Option<super::timer::RenderTimer>,
}

fn storage_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn texture_entry(binding: u32, filterable: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

fn module(device: &wgpu::Device, name: &str) -> Result<wgpu::ShaderModule, RenderError> {
    let src =
        shader_source(name).map_err(|e| RenderError::Shader { name: name.to_string(), message: e.to_string() })?;
    Ok(device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(name),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    }))
}

/// One render pipeline description, kept small so the table below reads as the pass list.
struct PipeDesc<'a> {
    label: &'a str,
    module: &'a wgpu::ShaderModule,
    layout: &'a wgpu::PipelineLayout,
    vs: &'a str,
    fs: &'a str,
    format: wgpu::TextureFormat,
    blend: Option<wgpu::BlendState>,
    /// (depth write, compare), or None without a depth attachment.
    depth: Option<(bool, wgpu::CompareFunction)>,
}

fn pipeline(device: &wgpu::Device, d: PipeDesc) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(d.label),
        layout: Some(d.layout),
        vertex: wgpu::VertexState {
            module: d.module,
            entry_point: Some(d.vs),
            compilation_options: Default::default(),
            buffers: &[],
        },
        fragment: Some(wgpu::FragmentState {
            module: d.module,
            entry_point: Some(d.fs),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: d.format,
                blend: d.blend,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: d.depth.map(|(write, compare)| wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(write),
            depth_compare: Some(compare),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        multiview_mask: None,
        cache: None,
    })
}

const ADDITIVE: wgpu::BlendState = wgpu::BlendState {
    color: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    },
    alpha: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    },
};

impl Renderer {
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Renderer, RenderError> {
        let camera_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("render.camera"),
            size: std::mem::size_of::<CameraGpu>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let camera_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("render.camera_layout"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let camera_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("render.camera_group"),
            layout: &camera_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: camera_buf.as_entire_binding() }],
        });
        let particle_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("render.particle_layout"),
            entries: &(0..7).map(storage_entry).collect::<Vec<_>>(),
        });
        let shape_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("render.shape_layout"),
            entries: &[storage_entry(0)],
        });
        let fluid_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("render.fluid_layout"),
            entries: &[
                texture_entry(0, false),
                texture_entry(1, false),
                texture_entry(2, true),
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let layout = |label: &str, second: &wgpu::BindGroupLayout| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[Some(&camera_layout), Some(second)],
                immediate_size: 0,
            })
        };
        let particle_pl = layout("render.particles", &particle_layout);
        let shape_pl = layout("render.shapes", &shape_layout);
        let fluid_pl = layout("render.fluid", &fluid_layout);
        let particles = module(device, "render_particles")?;
        let shapes = module(device, "render_shapes")?;
        let fluid = module(device, "render_fluid")?;
        let less = Some((true, wgpu::CompareFunction::Less));
        let p = |label, m, l, vs, fs, format, blend, depth| {
            pipeline(device, PipeDesc { label, module: m, layout: l, vs, fs, format, blend, depth })
        };
        let tissue = p("render.tissue", &particles, &particle_pl, "vs_tissue", "fs_tissue", SCENE_FORMAT, None, less);
        let blood_plain =
            p("render.blood_plain", &particles, &particle_pl, "vs_blood", "fs_blood_plain", SCENE_FORMAT, None, less);
        let blood_thickness = p(
            "render.blood_thickness",
            &particles,
            &particle_pl,
            "vs_blood",
            "fs_blood_thickness",
            THICKNESS_FORMAT,
            Some(ADDITIVE),
            Some((false, wgpu::CompareFunction::Less)),
        );
        let blood_depth = p(
            "render.blood_depth",
            &particles,
            &particle_pl,
            "vs_blood",
            "fs_blood_depth",
            FLUID_DEPTH_FORMAT,
            None,
            less,
        );
        let shapes_opaque =
            p("render.shapes_opaque", &shapes, &shape_pl, "vs_shape", "fs_shape", SCENE_FORMAT, None, less);
        let shapes_translucent = p(
            "render.shapes_translucent",
            &shapes,
            &shape_pl,
            "vs_shape",
            "fs_shape",
            SCENE_FORMAT,
            Some(wgpu::BlendState::ALPHA_BLENDING),
            Some((false, wgpu::CompareFunction::Less)),
        );
        let filter_h =
            p("render.filter_h", &fluid, &fluid_pl, "vs_fullscreen", "fs_filter_h", FLUID_DEPTH_FORMAT, None, None);
        let filter_v =
            p("render.filter_v", &fluid, &fluid_pl, "vs_fullscreen", "fs_filter_v", FLUID_DEPTH_FORMAT, None, None);
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("render.scene_sampler"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            address_mode_u: wgpu::AddressMode::ClampToEdge,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            ..Default::default()
        });
        let shape_capacity = 16;
        let (shape_buf, shape_group) = Self::shape_storage(device, &shape_layout, shape_capacity);
        Ok(Renderer {
            device: device.clone(),
            queue: queue.clone(),
            camera_buf,
            camera_group,
            particle_layout,
            shape_layout,
            fluid_layout,
            sampler,
            tissue,
            blood_plain,
            blood_thickness,
            blood_depth,
            shapes_opaque,
            shapes_translucent,
            filter_h,
            filter_v,
            fluid_module: fluid,
            fluid_pipeline_layout: fluid_pl,
            composite: HashMap::new(),
            shape_buf,
            shape_capacity,
            shape_group,
            targets: None,
            settings: RenderSettings::default(),
            timer: super::timer::RenderTimer::new(device, queue),
        })
    }

    fn shape_storage(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        capacity: u64,
    ) -> (wgpu::Buffer, wgpu::BindGroup) {
        let buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("render.shapes"),
            size: capacity * std::mem::size_of::<ShapeGpu>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("render.shape_group"),
            layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: buf.as_entire_binding() }],
        });
        (buf, group)
    }

    /// The bind group of one published particle set (create once per set, reuse every frame).
    pub fn bind_frame(&self, frame: &FrameBuffers) -> wgpu::BindGroup {
        let bufs = [
            &frame.liquid_pos,
            &frame.solid_pos,
            &frame.solid_dens,
            &frame.solid_stress,
            &frame.bond_count,
            &frame.bond_count0,
            &frame.solid_flags,
        ];
        let entries: Vec<wgpu::BindGroupEntry> = bufs
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("render.particle_group"),
            layout: &self.particle_layout,
            entries: &entries,
        })
    }

    fn composite_pipeline(&mut self, format: wgpu::TextureFormat) -> &wgpu::RenderPipeline {
        let (device, module, layout) = (&self.device, &self.fluid_module, &self.fluid_pipeline_layout);
        self.composite.entry(format).or_insert_with(|| {
            pipeline(
                device,
                PipeDesc {
                    label: "render.composite",
                    module,
                    layout,
                    vs: "vs_fullscreen",
                    fs: "fs_composite",
                    format,
                    blend: None,
                    depth: None,
                },
            )
        })
    }

    fn ensure_targets(&mut self, size: (u32, u32)) {
        if self.targets.as_ref().is_some_and(|t| t.size == size) {
            return;
        }
        let texture = |label: &str, format: wgpu::TextureFormat| {
            self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        };
        let view = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let scene = view(&texture("render.scene", SCENE_FORMAT));
        let depth = view(&texture("render.depth", DEPTH_FORMAT));
        let fluid_a_tex = texture("render.fluid_a", FLUID_DEPTH_FORMAT);
        let fluid_a = view(&fluid_a_tex);
        let fluid_b = view(&texture("render.fluid_b", FLUID_DEPTH_FORMAT));
        let thickness_tex = texture("render.thickness", THICKNESS_FORMAT);
        let thickness = view(&thickness_tex);
        let group = |depth_in: &wgpu::TextureView| {
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("render.fluid_group"),
                layout: &self.fluid_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(depth_in) },
                    wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&thickness) },
                    wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&scene) },
                    wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::Sampler(&self.sampler) },
                ],
            })
        };
        let read_a = group(&fluid_a);
        let read_b = group(&fluid_b);
        self.targets = Some(Targets {
            size,
            scene,
            depth,
            fluid_a,
            fluid_b,
            thickness,
            fluid_a_tex,
            thickness_tex,
            read_a,
            read_b,
        });
    }

    /// The uniform of one frame.
    pub fn camera_uniform(&self, camera: &OrbitCamera, size: (u32, u32), scene: &Scene) -> CameraGpu {
        let s = &self.settings;
        let (w, h) = (size.0 as f32, size.1 as f32);
        let view = camera.view();
        let proj = camera.proj(w / h.max(1.0));
        // Light from above-front-left of the viewer, fixed to the camera.
        let light = Vec3::new(-0.35, 0.75, 0.55).normalize();
        let r_blood = 0.5 * scene.dx_liquid * s.blood_radius;
        CameraGpu {
            view: view.to_cols_array_2d(),
            proj: proj.to_cols_array_2d(),
            light: [light.x, light.y, light.z, 0.28],
            viewport: [w, h, 1.0 / w.max(1.0), 1.0 / h.max(1.0)],
            draw: [0.5 * scene.dx_solid * s.tissue_radius, r_blood, s.field as u32 as f32, s.field_scale],
            fluid: [s.absorption, s.filter_radius_px, 2.0 * r_blood, 0.6],
            background: [s.background[0], s.background[1], s.background[2], if s.fluid { 1.0 } else { 0.0 }],
        }
    }

    /// The boundary objects as shape instances (simulation coordinates): opaque first, then the
    /// translucent walls; returns the split.
    fn shapes(&self, scene: &Scene) -> (Vec<ShapeGpu>, u32) {
        let o = scene.origin;
        let sim = |p: [f64; 3]| [(p[0] - o[0]) as f32, (p[1] - o[1]) as f32, (p[2] - o[2]) as f32, 0.0];
        let mut opaque = Vec::new();
        let mut translucent = Vec::new();
        for pose in scene.objects {
            let tool = pose.tool.is_some();
            if !tool && !self.settings.show_walls {
                continue;
            }
            // a moulded bed's box only bounds its particles (drawing it would hide the organ in it):
            // its particles are drawn instead, as overlapping balls — the abdominal organs' surface
            if pose.moulded {
                let r = [BED_BALL * scene.dx_solid, 0.0, 0.0, 0.0];
                opaque.extend(pose.bed.iter().map(|p| ShapeGpu {
                    a: sim(*p),
                    b: r,
                    colour: BED_COLOUR,
                    kind: [1, 0, 0, 0],
                }));
                continue;
            }
            let colour = if tool { [0.62, 0.64, 0.68, 1.0] } else { [0.55, 0.58, 0.62, 0.35] };
            let scalpel = pose.tool.as_ref().is_some_and(|t| t.kind == crate::scenario::ToolKind::Scalpel);
            let shape = match &pose.shape {
                Region::Box { min, max } if scalpel => {
                    let (blade, handle) = scalpel_shapes(sim(*min), sim(*max));
                    opaque.extend(handle);
                    blade
                }
                Region::Box { min, max } => ShapeGpu { a: sim(*min), b: sim(*max), colour, kind: [0; 4] },
                Region::Sphere { centre, radius } => {
                    ShapeGpu { a: sim(*centre), b: [*radius as f32, 0.0, 0.0, 0.0], colour, kind: [1, 0, 0, 0] }
                }
            };
            if tool { opaque.push(shape) } else { translucent.push(shape) }
        }
        let n_opaque = opaque.len() as u32;
        opaque.extend(translucent);
        (opaque, n_opaque)
    }

    /// Encodes one frame into `target` (a view of a `size` texture of `format`).
    pub fn draw(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
        size: (u32, u32),
        camera: &OrbitCamera,
        scene: &Scene,
    ) -> Result<(), RenderError> {
        let limit = self.device.limits().max_texture_dimension_2d;
        if size.0 == 0 || size.1 == 0 || size.0 > limit || size.1 > limit {
            return Err(RenderError::BadSize { width: size.0, height: size.1, limit });
        }
        self.ensure_targets(size);
        if let Some(tm) = &mut self.timer {
            tm.begin_frame();
        }
        let cam = self.camera_uniform(camera, size, scene);
        self.queue.write_buffer(&self.camera_buf, 0, bytemuck::bytes_of(&cam));
        let (shapes, n_opaque) = self.shapes(scene);
        if shapes.len() as u64 > self.shape_capacity {
            self.shape_capacity = (shapes.len() as u64).next_power_of_two();
            let (b, g) = Self::shape_storage(&self.device, &self.shape_layout, self.shape_capacity);
            self.shape_buf = b;
            self.shape_group = g;
        }
        if !shapes.is_empty() {
            self.queue.write_buffer(&self.shape_buf, 0, bytemuck::cast_slice(&shapes));
        }
        self.composite_pipeline(format);
        let Some(t) = self.targets.as_ref() else { return Ok(()) };
        let timer = &mut self.timer;
        let bg = self.settings.background;
        let fluid = self.settings.fluid;
        let clear_colour = wgpu::Color { r: bg[0] as f64, g: bg[1] as f64, b: bg[2] as f64, a: 1.0 };
        fn colour_att(view: &wgpu::TextureView, clear: wgpu::Color) -> wgpu::RenderPassColorAttachment<'_> {
            wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Store },
            }
        }
        let depth_att = |load: wgpu::LoadOp<f32>| wgpu::RenderPassDepthStencilAttachment {
            view: &t.depth,
            depth_ops: Some(wgpu::Operations { load, store: wgpu::StoreOp::Store }),
            stencil_ops: None,
        };
        // 1. scene
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("render.scene"),
                color_attachments: &[Some(colour_att(&t.scene, clear_colour))],
                depth_stencil_attachment: Some(depth_att(wgpu::LoadOp::Clear(1.0))),
                timestamp_writes: timer.as_mut().and_then(|t| t.writes(0)),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &self.camera_group, &[]);
            if n_opaque > 0 {
                pass.set_pipeline(&self.shapes_opaque);
                pass.set_bind_group(1, &self.shape_group, &[]);
                pass.draw(0..36, 0..n_opaque);
            }
            if let Some((group, n_liquid, n_solid)) = scene.particles {
                pass.set_bind_group(1, group, &[]);
                if n_solid > 0 {
                    pass.set_pipeline(&self.tissue);
                    pass.draw(0..6, 0..n_solid);
                }
                if !fluid && n_liquid > 0 {
                    pass.set_pipeline(&self.blood_plain);
                    pass.draw(0..6, 0..n_liquid);
                }
            }
            if (shapes.len() as u32) > n_opaque {
                pass.set_pipeline(&self.shapes_translucent);
                pass.set_bind_group(1, &self.shape_group, &[]);
                pass.draw(0..36, n_opaque..shapes.len() as u32);
            }
        }
        let n_liquid = scene.particles.map_or(0, |p| p.1);
        let blood = fluid && n_liquid > 0;
        // 2. thickness, 3. front depth (both cleared even without blood: the composite reads them)
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("render.blood_thickness"),
                color_attachments: &[Some(colour_att(&t.thickness, wgpu::Color::TRANSPARENT))],
                depth_stencil_attachment: Some(depth_att(wgpu::LoadOp::Load)),
                timestamp_writes: timer.as_mut().and_then(|t| t.writes(1)),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if let (true, Some((group, n, _))) = (blood, scene.particles) {
                pass.set_pipeline(&self.blood_thickness);
                pass.set_bind_group(0, &self.camera_group, &[]);
                pass.set_bind_group(1, group, &[]);
                pass.draw(0..6, 0..n);
            }
        }
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("render.blood_depth"),
                color_attachments: &[Some(colour_att(&t.fluid_a, wgpu::Color::TRANSPARENT))],
                depth_stencil_attachment: Some(depth_att(wgpu::LoadOp::Load)),
                timestamp_writes: timer.as_mut().and_then(|t| t.writes(2)),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if let (true, Some((group, n, _))) = (blood, scene.particles) {
                pass.set_pipeline(&self.blood_depth);
                pass.set_bind_group(0, &self.camera_group, &[]);
                pass.set_bind_group(1, group, &[]);
                pass.draw(0..6, 0..n);
            }
        }
        // 4. bilateral filter A → B → A
        if blood && self.settings.filter_radius_px >= 1.0 {
            for (k, (label, pipe, read, write)) in [
                ("render.filter_h", &self.filter_h, &t.read_a, &t.fluid_b),
                ("render.filter_v", &self.filter_v, &t.read_b, &t.fluid_a),
            ]
            .into_iter()
            .enumerate()
            {
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some(label),
                    color_attachments: &[Some(colour_att(write, wgpu::Color::TRANSPARENT))],
                    depth_stencil_attachment: None,
                    timestamp_writes: timer.as_mut().and_then(|t| t.writes(3 + k)),
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                pass.set_pipeline(pipe);
                pass.set_bind_group(0, &self.camera_group, &[]);
                pass.set_bind_group(1, read, &[]);
                pass.draw(0..3, 0..1);
            }
        }
        // 5. composite into the target
        {
            let Some(composite) = self.composite.get(&format) else { return Ok(()) };
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("render.composite"),
                color_attachments: &[Some(colour_att(target, clear_colour))],
                depth_stencil_attachment: None,
                timestamp_writes: timer.as_mut().and_then(|t| t.writes(5)),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(composite);
            pass.set_bind_group(0, &self.camera_group, &[]);
            pass.set_bind_group(1, &t.read_a, &[]);
            pass.draw(0..3, 0..1);
        }
        if let Some(tm) = timer {
            tm.end_frame(encoder);
        }
        Ok(())
    }

    /// Call after submitting the encoder of [`Renderer::draw`]: starts the timer's readback.
    pub fn submitted(&mut self) {
        if let Some(tm) = &mut self.timer {
            tm.submitted();
        }
    }

    /// GPU milliseconds per pass of the last timed frame (empty without timestamp queries).
    pub fn pass_ms(&self) -> &[(&'static str, f64)] {
        self.timer.as_ref().map_or(&[], |t| &t.last_ms)
    }

    /// The intermediate fluid textures of the last frame — filtered eye depth (R32Float) and
    /// thickness (R16Float) — for tests of the screen-space fluid passes.
    pub fn fluid_textures(&self) -> Option<(&wgpu::Texture, &wgpu::Texture)> {
        self.targets.as_ref().map(|t| (&t.fluid_a_tex, &t.thickness_tex))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The liver's scalpel box (x thin, y tall, z long): a wedge thin along x with its edge at the
    /// bottom of y, and a handle on the spine (above the box's top, three blade-thicknesses wide);
    /// a cube gets no handle.
    #[test]
    fn scalpel_box_becomes_a_blade_and_a_handle() {
        let (a, b) = ([-0.09, 0.075, -0.045, 0.0], [-0.0825, 0.105, 0.045, 0.0]);
        let (blade, handle) = scalpel_shapes(a, b);
        assert_eq!((blade.a, blade.b, blade.kind), (a, b, [2, 0, 1, 0]));
        let h = handle.expect("handle");
        assert_eq!(h.a[1], b[1]);
        assert!((h.b[1] - (b[1] + 0.6 * 0.03)).abs() < 1e-6);
        assert!(((h.b[0] - h.a[0]) - 3.0 * 0.0075).abs() < 1e-6);
        assert!(h.a[2] > a[2] && h.b[2] < b[2] && h.kind[0] == 0);
        assert!(scalpel_shapes([0.0; 4], [1.0, 1.0, 1.0, 0.0]).1.is_none());
    }
}
