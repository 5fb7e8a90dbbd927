//! Host↔GPU structs of the renderer, each mirroring the WGSL struct of the same name
//! (`shaders/render_common.wgsl`, `shaders/render_shapes.wgsl`; must be kept in sync — the shader
//! validation test compares their sizes with naga's layout).

use bytemuck::{Pod, Zeroable};

/// `Camera` (render_common.wgsl): the per-frame uniform of bind group 0.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct CameraGpu {
    pub view: [[f32; 4]; 4],
    pub proj: [[f32; 4]; 4],
    /// xyz: direction towards the light (view space); w: ambient fraction.
    pub light: [f32; 4],
    /// width, height, 1/width, 1/height \[px\].
    pub viewport: [f32; 4],
    /// tissue radius \[m\], blood radius \[m\], field mode, field scale.
    pub draw: [f32; 4],
    /// absorption [1/m], filter radius \[px\], depth falloff \[m\], refraction strength.
    pub fluid: [f32; 4],
    /// rgb background (linear), w: 1 = screen-space fluid, 0 = plain spheres.
    pub background: [f32; 4],
}

/// `Shape` (render_shapes.wgsl): one boundary object to draw.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, Default)]
pub struct ShapeGpu {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub colour: [f32; 4],
    pub kind: [u32; 4],
}

/// What colours the tissue (`FIELD_*` in render_particles.wgsl).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FieldMode {
    /// Liver parenchyma, capsule and ligaments in their own colours.
    #[default]
    Plain = 0,
    /// von Mises equivalent of the deviatoric Cauchy stress \[Pa\].
    Stress = 1,
    /// Liquid volume fraction nˡ.
    LiquidFraction = 2,
    /// Fraction of a particle's bonds that broke (Alg. 2).
    BrokenBonds = 3,
}

impl FieldMode {
    pub const ALL: [FieldMode; 4] =
        [FieldMode::Plain, FieldMode::Stress, FieldMode::LiquidFraction, FieldMode::BrokenBonds];

    pub fn name(self) -> &'static str {
        match self {
            FieldMode::Plain => "tissue",
            FieldMode::Stress => "stress (von Mises)",
            FieldMode::LiquidFraction => "liquid fraction nˡ",
            FieldMode::BrokenBonds => "broken bonds",
        }
    }

    /// Default full-scale value of the colour map.
    pub fn default_scale(self) -> f32 {
        match self {
            FieldMode::Plain => 1.0,
            FieldMode::Stress => 2000.0,
            FieldMode::LiquidFraction => 0.6,
            FieldMode::BrokenBonds => 0.5,
        }
    }
}
