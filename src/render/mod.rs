//! wgpu rendering of the viewport: the radiosity mesh and overlay lines, shown in egui through an
//! `egui_wgpu` paint callback — drawn straight into egui's render pass when that pass has a depth
//! buffer (the native window: `NativeOptions::depth_buffer`), else into an offscreen colour +
//! depth target that is then copied into egui's pass.
//!
//! ## How it works
//! ```text
//!  UI thread (each frame)              egui_wgpu renderer
//!  ─────────────────────              ──────────────────────────────────────────────────────
//!  ViewportCallback { frame,     ──►  prepare(): upload Geometry if its generation changed,
//!    Arc<Geometry>, generation }        write the uniforms
//!                                       [offscreen] render mesh + lines into the Rgba8Unorm +
//!                                       Depth32Float target
//!                                     paint():   [direct] mesh, background behind it, lines,
//!                                                 into egui's pass (viewport = callback rect)
//!                                                [offscreen] blit the image into egui's pass
//! ```
//! Drawing directly saves, per frame, the clear of an own colour + depth target and a full-size
//! copy; on a CPU rasteriser (lavapipe) those are whole-viewport passes over memory. The
//! background is drawn *after* the mesh, at the far plane with the depth test "less or equal", so
//! it shades only the pixels the mesh left empty instead of clearing every pixel first.
//!
//! Pipelines are built once and kept in egui's `CallbackResources` (the egui custom-3D pattern).
//! Each view drawn has its own slot of uniforms, buffers and offscreen target
//! ([`ViewportCallback::slot`]): slot 0 is the viewport, 1, 2, … the split view's panes, which
//! share the pipelines and draw side by side in one frame.
//! The offscreen target serves the tests (which read the exact viewport pixels back,
//! [`SceneRenderer::read_pixels`]) and egui passes without depth (egui_kittest). Screenshots
//! (the button, `--screenshot`) capture egui's whole frame either way and crop the viewport.
//!
//! Shaders: `shaders/mesh.wgsl` (radiosity, tone mapping, back faces, highlight, background),
//! `shaders/lines.wgsl` (overlays), `shaders/blit.wgsl` (copy into egui's pass).

pub mod geometry;
pub mod gpu_data;
pub mod snapshot;

use eframe::egui_wgpu;
use eframe::wgpu;
use eframe::wgpu::util::DeviceExt;
pub use gpu_data::{LineVertex, MeshVertex, NO_SELECTION, OVERLAY_PICKED, OVERLAY_QUADTREE, Uniforms};
use std::sync::Arc;

/// WGSL sources, one per pipeline (also parsed by the naga test).
pub const SHADERS: [(&str, &str); 3] = [
    ("mesh.wgsl", include_str!("../../shaders/mesh.wgsl")),
    ("lines.wgsl", include_str!("../../shaders/lines.wgsl")),
    ("blit.wgsl", include_str!("../../shaders/blit.wgsl")),
];

/// Format of the offscreen colour target (display-encoded values).
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Format of the offscreen depth buffer, and of egui's when the viewer asks for one
/// (`NativeOptions::depth_buffer = 32`, see [`HOST_DEPTH_BITS`]).
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// `NativeOptions::depth_buffer` that gives egui's pass a [`DEPTH_FORMAT`] depth buffer.
pub const HOST_DEPTH_BITS: u8 = 32;

/// Everything drawn in the viewport, in the scene's local frame.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    /// Indexed triangles (quadtree edges and the picked outline are drawn by its shader).
    pub mesh: geometry::Mesh,
    /// Link lines.
    pub links: Vec<LineVertex>,
    /// Draw links over everything (x-ray) instead of depth-testing them.
    pub links_xray: bool,
    /// Overlay lines on the surfaces (critical edges, artifact samples), always depth-tested
    /// ([`crate::present::mesh_overlay`] lifts them off their surface).
    pub overlay: Vec<LineVertex>,
}

/// Per-frame settings of one render (the background colour is `uniforms.background`).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct FrameParams {
    pub uniforms: Uniforms,
    /// Target size in pixels.
    pub size: [u32; 2],
}

/// The pipelines that draw the scene into one kind of pass (colour format + depth format).
struct ScenePipelines {
    mesh: wgpu::RenderPipeline,
    lines: wgpu::RenderPipeline,
    xray: wgpu::RenderPipeline,
    /// Fills what the mesh left empty (only where there is no clear to the background).
    background: wgpu::RenderPipeline,
}

struct Target {
    size: [u32; 2],
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    blit_group: wgpu::BindGroup,
}

struct GpuBuffer {
    buffer: wgpu::Buffer,
    count: u32,
}

/// What one view of the scene owns: its uniforms, the buffers of its geometry and its offscreen
/// target. Slot 0 is the main viewport; the split view's panes draw into slots 1, 2, …
/// (each pane its own uniforms: in the direct path all of them are written before egui's pass).
struct Slot {
    uniform_buffer: wgpu::Buffer,
    uniform_group: wgpu::BindGroup,
    mesh: Option<GpuBuffer>,
    mesh_indices: Option<GpuBuffer>,
    links: Option<GpuBuffer>,
    links_xray: bool,
    overlay: Option<GpuBuffer>,
    target: Option<Target>,
    /// Generation of the uploaded geometry (see [`ViewportCallback`]).
    generation: u64,
    /// The settings of the image in the target; a frame with the same settings and geometry
    /// reuses it instead of rasterising the scene again (a still camera costs only the blit).
    drawn: Option<FrameParams>,
}

impl Slot {
    fn new(device: &wgpu::Device, uniform_layout: &wgpu::BindGroupLayout) -> Slot {
        let uniform_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("radlab uniforms"),
            contents: bytemuck::bytes_of(&Uniforms::zeroed()),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let uniform_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("radlab uniforms"),
            layout: uniform_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: uniform_buffer.as_entire_binding() }],
        });
        Slot {
            uniform_buffer,
            uniform_group,
            mesh: None,
            mesh_indices: None,
            links: None,
            links_xray: false,
            overlay: None,
            target: None,
            generation: u64::MAX,
            drawn: None,
        }
    }
}

/// The viewport's pipelines, and the buffers and offscreen target of each view drawn ([`Slot`]).
pub struct SceneRenderer {
    /// Into the offscreen Rgba8Unorm + Depth32Float target.
    offscreen: ScenePipelines,
    /// Straight into egui's pass, when it has a [`DEPTH_FORMAT`] depth buffer.
    direct: Option<ScenePipelines>,
    blit_pipeline: wgpu::RenderPipeline,
    uniform_layout: wgpu::BindGroupLayout,
    blit_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    /// Slot 0: the main viewport; then the split view's panes (created on first use).
    slots: Vec<Slot>,
    /// Wall time of the last [`SceneRenderer::set_geometry`] (seconds), for the benchmark.
    pub last_upload_s: f64,
}

fn shader(device: &wgpu::Device, name: &str) -> wgpu::ShaderModule {
    let src = SHADERS.iter().find(|(n, _)| *n == name).map_or("", |(_, s)| *s);
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(name),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    })
}

impl ScenePipelines {
    /// Pipelines for a pass with this colour and depth format. An *Srgb colour format encodes on
    /// write, so the shaders decode their display-encoded output first (`DECODE_OUTPUT`).
    fn new(
        device: &wgpu::Device,
        layout: &wgpu::PipelineLayout,
        color: wgpu::TextureFormat,
        depth_format: wgpu::TextureFormat,
    ) -> ScenePipelines {
        let decode = [("DECODE_OUTPUT", if color.is_srgb() { 1.0 } else { 0.0 })];
        let options = wgpu::PipelineCompilationOptions { constants: &decode, ..Default::default() };
        let depth = |write: bool, compare: wgpu::CompareFunction| wgpu::DepthStencilState {
            format: depth_format,
            depth_write_enabled: Some(write),
            depth_compare: Some(compare),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        };
        let mesh_module = shader(device, "mesh.wgsl");
        let mesh_attrs = wgpu::vertex_attr_array![
            0 => Float32x3, 1 => Uint32, 2 => Float32x3, 3 => Float32x2, 4 => Unorm8x4
        ];
        let opaque =
            [Some(wgpu::ColorTargetState { format: color, blend: None, write_mask: wgpu::ColorWrites::ALL })];
        let mesh = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("radlab mesh"),
            layout: Some(layout),
            vertex: wgpu::VertexState {
                module: &mesh_module,
                entry_point: Some("vs_main"),
                compilation_options: options.clone(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: size_of::<MeshVertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &mesh_attrs,
                })],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                cull_mode: None, // back faces are drawn, distinctly (mesh.wgsl)
                ..wgpu::PrimitiveState::default()
            },
            depth_stencil: Some(depth(true, wgpu::CompareFunction::Less)),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &mesh_module,
                entry_point: Some("fs_main"),
                compilation_options: options.clone(),
                targets: &opaque,
            }),
            multiview_mask: None,
            cache: None,
        });
        let background = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("radlab background"),
            layout: Some(layout),
            vertex: wgpu::VertexState {
                module: &mesh_module,
                entry_point: Some("vs_background"),
                compilation_options: options.clone(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(depth(false, wgpu::CompareFunction::LessEqual)),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &mesh_module,
                entry_point: Some("fs_background"),
                compilation_options: options.clone(),
                targets: &opaque,
            }),
            multiview_mask: None,
            cache: None,
        });

        let lines_module = shader(device, "lines.wgsl");
        let line_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4];
        let line_pipeline = |label: &str, compare: wgpu::CompareFunction| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(layout),
                vertex: wgpu::VertexState {
                    module: &lines_module,
                    entry_point: Some("vs_main"),
                    compilation_options: options.clone(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: size_of::<LineVertex>() as u64,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &line_attrs,
                    })],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::LineList,
                    ..wgpu::PrimitiveState::default()
                },
                depth_stencil: Some(depth(false, compare)),
                multisample: wgpu::MultisampleState::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &lines_module,
                    entry_point: Some("fs_main"),
                    compilation_options: options.clone(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: color,
                        blend: Some(wgpu::BlendState::ALPHA_BLENDING),
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        ScenePipelines {
            mesh,
            lines: line_pipeline("radlab lines", wgpu::CompareFunction::LessEqual),
            xray: line_pipeline("radlab lines x-ray", wgpu::CompareFunction::Always),
            background,
        }
    }
}

impl SceneRenderer {
    /// Build the pipelines. `output_format` is the format of egui's pass (its target format);
    /// `host_depth` its depth format, if it has a depth buffer: with [`DEPTH_FORMAT`] the scene
    /// is drawn straight into that pass, else through the offscreen target.
    #[must_use]
    pub fn new(
        device: &wgpu::Device,
        output_format: wgpu::TextureFormat,
        host_depth: Option<wgpu::TextureFormat>,
    ) -> SceneRenderer {
        let uniform_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("radlab uniforms"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: wgpu::BufferSize::new(size_of::<Uniforms>() as u64),
                },
                count: None,
            }],
        });
        let main_view = Slot::new(device, &uniform_layout);
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("radlab scene"),
            bind_group_layouts: &[Some(&uniform_layout)],
            immediate_size: 0,
        });
        let offscreen = ScenePipelines::new(device, &layout, COLOR_FORMAT, DEPTH_FORMAT);
        let direct = (host_depth == Some(DEPTH_FORMAT))
            .then(|| ScenePipelines::new(device, &layout, output_format, DEPTH_FORMAT));

        let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("radlab blit"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let blit_pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("radlab blit"),
            bind_group_layouts: &[Some(&blit_layout)],
            immediate_size: 0,
        });
        let blit_module = shader(device, "blit.wgsl");
        let blit_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("radlab blit"),
            layout: Some(&blit_pl),
            vertex: wgpu::VertexState {
                module: &blit_module,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &blit_module,
                entry_point: Some(if output_format.is_srgb() { "fs_decode" } else { "fs_copy" }),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: output_format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("radlab blit"),
            mag_filter: wgpu::FilterMode::Nearest,
            min_filter: wgpu::FilterMode::Nearest,
            ..wgpu::SamplerDescriptor::default()
        });
        SceneRenderer {
            offscreen,
            direct,
            blit_pipeline,
            uniform_layout,
            blit_layout,
            sampler,
            slots: vec![main_view],
            last_upload_s: 0.0,
        }
    }

    /// The slot of view `slot`, created (with those before it) on first use.
    fn slot_mut(&mut self, device: &wgpu::Device, slot: usize) -> &mut Slot {
        while self.slots.len() <= slot {
            self.slots.push(Slot::new(device, &self.uniform_layout));
        }
        &mut self.slots[slot]
    }

    /// Upload new geometry (replaces the previous buffers). Called only when the geometry
    /// changes (a new solution, display settings, the picked element), never per frame.
    pub fn set_geometry(&mut self, device: &wgpu::Device, geometry: &Geometry) {
        self.set_slot_geometry(device, 0, geometry);
    }

    /// [`SceneRenderer::set_geometry`] of view `slot` (0: the main viewport).
    pub fn set_slot_geometry(&mut self, device: &wgpu::Device, slot: usize, geometry: &Geometry) {
        fn upload<T: bytemuck::Pod>(
            device: &wgpu::Device,
            label: &str,
            data: &[T],
            usage: wgpu::BufferUsages,
        ) -> Option<GpuBuffer> {
            (!data.is_empty()).then(|| GpuBuffer {
                buffer: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(data),
                    usage,
                }),
                count: data.len() as u32,
            })
        }
        let (vertex, index) = (wgpu::BufferUsages::VERTEX, wgpu::BufferUsages::INDEX);
        let s = self.slot_mut(device, slot);
        s.mesh = upload(device, "radlab mesh", &geometry.mesh.vertices, vertex);
        s.mesh_indices = upload(device, "radlab mesh indices", &geometry.mesh.indices, index);
        s.links = upload(device, "radlab links", &geometry.links, vertex);
        s.links_xray = geometry.links_xray;
        s.overlay = upload(device, "radlab overlay lines", &geometry.overlay, vertex);
        s.drawn = None;
    }

    fn ensure_target(&mut self, device: &wgpu::Device, slot: usize, size: [u32; 2]) {
        let size = [size[0].max(1), size[1].max(1)];
        if self.slot_mut(device, slot).target.as_ref().is_some_and(|t| t.size == size) {
            return;
        }
        let extent = wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 };
        let color = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("radlab viewport colour"),
            size: extent,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: COLOR_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let depth = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("radlab viewport depth"),
            size: extent,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        let color_view = color.create_view(&wgpu::TextureViewDescriptor::default());
        let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());
        let blit_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("radlab blit"),
            layout: &self.blit_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&color_view),
                },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(&self.sampler) },
            ],
        });
        let s = &mut self.slots[slot];
        s.target = Some(Target { size, color, color_view, depth_view, blit_group });
        s.drawn = None;
    }

    /// Render the scene into the offscreen target (created or resized to `frame.size`).
    pub fn render(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        frame: &FrameParams,
    ) {
        self.render_slot(device, queue, encoder, 0, frame);
    }

    /// [`SceneRenderer::render`] of view `slot` into its own target.
    pub fn render_slot(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        slot: usize,
        frame: &FrameParams,
    ) {
        self.ensure_target(device, slot, frame.size);
        let s = &mut self.slots[slot];
        if s.drawn.as_ref() == Some(frame) && s.target.is_some() {
            return;
        }
        queue.write_buffer(&s.uniform_buffer, 0, bytemuck::bytes_of(&frame.uniforms));
        s.drawn = Some(*frame);
        let s = &self.slots[slot];
        let Some(target) = &s.target else { return };
        let [r, g, b, a] = frame.uniforms.background.map(f64::from);
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("radlab viewport"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &target.color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &target.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        draw(s, &mut pass, &self.offscreen, false);
    }

    /// True when the scene is drawn straight into egui's pass ([`SceneRenderer::paint_direct`]).
    #[must_use]
    pub fn draws_direct(&self) -> bool {
        self.direct.is_some()
    }

    /// Before [`SceneRenderer::paint_direct`]: write this frame's uniforms.
    pub fn prepare_direct(&mut self, queue: &wgpu::Queue, frame: &FrameParams) {
        self.prepare_direct_slot(queue, 0, frame);
    }

    /// [`SceneRenderer::prepare_direct`] of view `slot` (which must exist: its geometry was set).
    fn prepare_direct_slot(&mut self, queue: &wgpu::Queue, slot: usize, frame: &FrameParams) {
        let Some(s) = self.slots.get_mut(slot) else { return };
        if s.drawn.as_ref() != Some(frame) {
            queue.write_buffer(&s.uniform_buffer, 0, bytemuck::bytes_of(&frame.uniforms));
            s.drawn = Some(*frame);
        }
    }

    /// Draw the scene into a pass whose colour target has the `output_format` and whose depth
    /// buffer is a [`DEPTH_FORMAT`] one cleared to 1 (egui's, with the viewport set to the
    /// callback rect): the mesh, the background where the mesh left pixels empty, the lines.
    /// Returns false (drawing nothing) without direct pipelines.
    pub fn paint_direct(&self, pass: &mut wgpu::RenderPass<'_>) -> bool {
        self.paint_direct_slot(pass, 0)
    }

    fn paint_direct_slot(&self, pass: &mut wgpu::RenderPass<'_>, slot: usize) -> bool {
        let Some(p) = &self.direct else { return false };
        if let Some(s) = self.slots.get(slot) {
            draw(s, pass, p, true);
        }
        true
    }

    /// Draw the offscreen image into egui's pass (its viewport already set to the callback rect).
    pub fn blit(&self, pass: &mut wgpu::RenderPass<'_>) {
        self.blit_slot(pass, 0);
    }

    fn blit_slot(&self, pass: &mut wgpu::RenderPass<'_>, slot: usize) {
        if let Some(t) = self.slots.get(slot).and_then(|s| s.target.as_ref()) {
            pass.set_pipeline(&self.blit_pipeline);
            pass.set_bind_group(0, &t.blit_group, &[]);
            pass.draw(0..3, 0..1);
        }
    }

    /// Size of the current offscreen target.
    #[must_use]
    pub fn target_size(&self) -> Option<[u32; 2]> {
        self.slots[0].target.as_ref().map(|t| t.size)
    }

    /// Read the offscreen image back: `(width, height, RGBA8 rows)`. Blocks until the GPU is done.
    pub fn read_pixels(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<RgbaImage, String> {
        let t = self.slots[0].target.as_ref().ok_or("nothing rendered yet")?;
        read_texture(device, queue, &t.color)
    }
}

/// Draw one view: the mesh, then (without a clear behind it) the background, then the link lines
/// and the overlay lines.
fn draw(s: &Slot, pass: &mut wgpu::RenderPass<'_>, pipelines: &ScenePipelines, background: bool) {
    pass.set_bind_group(0, &s.uniform_group, &[]);
    if let (Some(m), Some(i)) = (&s.mesh, &s.mesh_indices) {
        pass.set_pipeline(&pipelines.mesh);
        pass.set_vertex_buffer(0, m.buffer.slice(..));
        pass.set_index_buffer(i.buffer.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..i.count, 0, 0..1);
    }
    if background {
        pass.set_pipeline(&pipelines.background);
        pass.draw(0..3, 0..1);
    }
    if let Some(l) = &s.links {
        pass.set_pipeline(if s.links_xray { &pipelines.xray } else { &pipelines.lines });
        pass.set_vertex_buffer(0, l.buffer.slice(..));
        pass.draw(0..l.count, 0..1);
    }
    if let Some(o) = &s.overlay {
        pass.set_pipeline(&pipelines.lines);
        pass.set_vertex_buffer(0, o.buffer.slice(..));
        pass.draw(0..o.count, 0..1);
    }
}

/// Read a 2-D texture with 4 bytes per texel (RGBA8 or BGRA8, returned as stored) back to the
/// CPU. Blocks until the GPU is done.
pub fn read_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
) -> Result<RgbaImage, String> {
    let (w, h) = (texture.width(), texture.height());
    let row = w * 4;
    let padded = row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("radlab read-back"),
        size: u64::from(padded) * u64::from(h),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder =
        device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("read-back") });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(h),
            },
        },
        wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
    );
    let index = queue.submit([encoder.finish()]);
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::Wait { submission_index: Some(index), timeout: Some(READBACK_TIMEOUT) })
        .map_err(|e| format!("GPU read-back: {e}"))?;
    rx.recv().map_err(|e| e.to_string())?.map_err(|e| format!("GPU read-back: {e}"))?;
    let data = slice.get_mapped_range().map_err(|e| format!("GPU read-back: {e:?}"))?;
    let mut pixels = Vec::with_capacity((row * h) as usize);
    for y in 0..h {
        let start = (y * padded) as usize;
        pixels.extend_from_slice(&data[start..start + row as usize]);
    }
    drop(data);
    buffer.unmap();
    Ok(RgbaImage { width: w, height: h, pixels })
}

/// Longest wait for a read-back (software rasterisers can be slow on big targets).
const READBACK_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(30);

use bytemuck::Zeroable;

/// A plain RGBA8 image (row-major, no padding).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RgbaImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u8>,
}

impl RgbaImage {
    /// The RGBA value at (x, y).
    #[must_use]
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = ((y * self.width + x) * 4) as usize;
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2], self.pixels[i + 3]]
    }

    /// Write as PNG (8-bit RGBA).
    pub fn save_png(&self, path: &std::path::Path) -> Result<(), String> {
        let file = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), self.width, self.height);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| format!("{}: {e}", path.display()))?;
        w.write_image_data(&self.pixels).map_err(|e| format!("{}: {e}", path.display()))?;
        w.finish().map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Read an 8-bit RGB or RGBA PNG.
    pub fn load_png(path: &std::path::Path) -> Result<RgbaImage, String> {
        let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut dec = png::Decoder::new(std::io::BufReader::new(file));
        dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
        let mut reader = dec.read_info().map_err(|e| format!("{}: {e}", path.display()))?;
        let mut buf = vec![0; reader.output_buffer_size().ok_or("PNG too large")?];
        let info = reader.next_frame(&mut buf).map_err(|e| format!("{}: {e}", path.display()))?;
        let data = &buf[..info.buffer_size()];
        let pixels = match info.color_type {
            png::ColorType::Rgba => data.to_vec(),
            png::ColorType::Rgb => data.chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 255]).collect(),
            png::ColorType::Grayscale => data.iter().flat_map(|&g| [g, g, g, 255]).collect(),
            png::ColorType::GrayscaleAlpha => {
                data.chunks_exact(2).flat_map(|c| [c[0], c[0], c[0], c[1]]).collect()
            }
            png::ColorType::Indexed => return Err(format!("{}: unexpanded palette PNG", path.display())),
        };
        Ok(RgbaImage { width: info.width, height: info.height, pixels })
    }

    /// A sub-rectangle (clamped to the image).
    #[must_use]
    pub fn crop(&self, x0: u32, y0: u32, w: u32, h: u32) -> RgbaImage {
        let x0 = x0.min(self.width);
        let y0 = y0.min(self.height);
        let w = w.min(self.width - x0);
        let h = h.min(self.height - y0);
        let mut pixels = Vec::with_capacity((w * h * 4) as usize);
        for y in y0..y0 + h {
            let s = ((y * self.width + x0) * 4) as usize;
            pixels.extend_from_slice(&self.pixels[s..s + (w * 4) as usize]);
        }
        RgbaImage { width: w, height: h, pixels }
    }

    /// Number of distinct RGB colours (a blank or failed render has very few).
    #[must_use]
    pub fn distinct_colors(&self) -> usize {
        let mut set: std::collections::HashSet<[u8; 3]> = std::collections::HashSet::new();
        for p in self.pixels.chunks_exact(4) {
            set.insert([p[0], p[1], p[2]]);
        }
        set.len()
    }
}

// ---------------------------------------------------------------------------------------------
// egui integration

/// The paint callback of the viewport: renders with the [`SceneRenderer`] stored in egui's
/// `CallbackResources` (inserted by the viewer at start-up).
pub struct ViewportCallback {
    pub frame: FrameParams,
    pub geometry: Arc<Geometry>,
    /// Bumped by the viewer whenever `geometry` changes; uploads happen only then.
    pub generation: u64,
    /// Which view this is: 0 the main viewport, 1, 2, … the split view's panes (each keeps its
    /// own buffers and target in the renderer).
    pub slot: usize,
}

impl egui_wgpu::CallbackTrait for ViewportCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen: &egui_wgpu::ScreenDescriptor,
        encoder: &mut wgpu::CommandEncoder,
        resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        if let Some(r) = resources.get_mut::<SceneRenderer>() {
            if r.slot_mut(device, self.slot).generation != self.generation {
                let started = std::time::Instant::now();
                r.set_slot_geometry(device, self.slot, &self.geometry);
                r.slots[self.slot].generation = self.generation;
                r.last_upload_s = started.elapsed().as_secs_f64();
            }
            if r.draws_direct() {
                r.prepare_direct_slot(queue, self.slot, &self.frame);
            } else {
                r.render_slot(device, queue, encoder, self.slot, &self.frame);
            }
        }
        Vec::new()
    }

    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        pass: &mut wgpu::RenderPass<'static>,
        resources: &egui_wgpu::CallbackResources,
    ) {
        if let Some(r) = resources.get::<SceneRenderer>()
            && !r.paint_direct_slot(pass, self.slot)
        {
            r.blit_slot(pass, self.slot);
        }
    }
}

use eframe::egui;
