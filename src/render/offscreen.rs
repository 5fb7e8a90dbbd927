//! Offscreen targets and readback: the renderer draws into a texture exactly as into a window, and
//! the pixels come back as an `image::RgbaImage` (PNG screenshots, `perfuse render`, render tests).

use super::renderer::RenderError;
use crate::sim::gpu::GpuError;

/// Colour format of offscreen frames: 8-bit sRGB, what a PNG stores.
pub const OFFSCREEN_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// A colour texture to render into and read back.
pub struct Offscreen {
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
    pub size: (u32, u32),
}

impl Offscreen {
    pub fn new(device: &wgpu::Device, size: (u32, u32)) -> Result<Offscreen, RenderError> {
        let limit = device.limits().max_texture_dimension_2d;
        if size.0 == 0 || size.1 == 0 || size.0 > limit || size.1 > limit {
            return Err(RenderError::BadSize { width: size.0, height: size.1, limit });
        }
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("render.offscreen"),
            size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: OFFSCREEN_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        Ok(Offscreen { texture, view, size })
    }

    /// Reads the frame back (blocking).
    pub fn read(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<image::RgbaImage, GpuError> {
        let raw = read_texture(device, queue, &self.texture, self.size, 4)?;
        image::RgbaImage::from_raw(self.size.0, self.size.1, raw).ok_or_else(|| GpuError::Readback {
            buffer: "offscreen".into(),
            message: "pixel buffer has the wrong size".into(),
        })
    }
}

/// Reads a whole 2-D texture of `bytes_per_pixel` back as tightly packed rows (blocking).
pub fn read_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    size: (u32, u32),
    bytes_per_pixel: u32,
) -> Result<Vec<u8>, GpuError> {
    let row = size.0 * bytes_per_pixel;
    let padded = row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("render.readback"),
        size: u64::from(padded) * u64::from(size.1),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("render.readback") });
    enc.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(padded), rows_per_image: None },
        },
        wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
    );
    queue.submit([enc.finish()]);
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::wait_indefinitely())?;
    match rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(GpuError::Readback { buffer: "texture".into(), message: e.to_string() }),
        Err(e) => return Err(GpuError::Readback { buffer: "texture".into(), message: e.to_string() }),
    }
    let data = slice
        .get_mapped_range()
        .map_err(|e| GpuError::Readback { buffer: "texture".into(), message: e.to_string() })?;
    let mut out = Vec::with_capacity((row * size.1) as usize);
    for y in 0..size.1 as usize {
        let start = y * padded as usize;
        out.extend_from_slice(&data[start..start + row as usize]);
    }
    drop(data);
    buffer.unmap();
    Ok(out)
}
