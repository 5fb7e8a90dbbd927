//! The GPU-resident state: one buffer per [`Slot`], sized once at creation (particle counts and the
//! bond capacity never change), plus the per-set grid uniforms and the readback helpers. Buffer sizes
//! are computed here only (STYLE §1: one place).

use super::bindings::Slot;
use super::device::GpuError;
use super::passes::GridOf;
use bytemuck::Pod;
use wgpu::util::DeviceExt;

/// Smallest buffer size: zero-sized buffers cannot be bound, empty sets still bind theirs, and a
/// runtime-sized array must hold one element of its struct (the largest per-particle one, common.wgsl's `LiquidMove`,
/// is 64 bytes; an empty object or motion table is bound as one zeroed 96-byte `ObjectGpu` /
/// `MotionGpu`).
const MIN_BYTES: u64 = 256;

/// All simulation buffers by slot; the grid-generic slots resolve per set.
pub struct SimBuffers {
    by_slot: Vec<Option<wgpu::Buffer>>,
    grid_set: [wgpu::Buffer; 4],
    /// Backups of the evolving buffers (the last good state, restored on divergence).
    backups: Vec<(Slot, wgpu::Buffer)>,
}

/// Buffers holding evolving state: copied to backups at the start of each batch of steps.
pub const STATE_SLOTS: &[Slot] = &[
    Slot::LiquidPos,
    Slot::LiquidVel,
    Slot::LiquidVelAdv,
    Slot::LiquidAcc,
    Slot::LiquidAcc0,
    Slot::LiquidDens,
    Slot::SolidPos,
    Slot::SolidVel,
    Slot::SolidVelAdv,
    Slot::SolidAcc,
    Slot::SolidAcc0,
    Slot::SolidDisp,
    Slot::SolidDens,
    Slot::SolidDrho,
    Slot::SolidDefGrad,
    Slot::SolidStress,
    Slot::BondTable,
    Slot::BondCount,
    Slot::BondLimit,
    Slot::LiquidId,
    // emitter volume accounts, cursors and counts
    Slot::EmitState,
    // the object poses at tⁿ (written on the GPU by `batch_motion`): restored with the state so a
    // re-run of a diverged batch step by step sees the same boundaries
    Slot::Objects,
];

fn usage(slot: Slot) -> wgpu::BufferUsages {
    if slot.is_uniform() {
        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST
    } else if slot == Slot::IndirectArgs {
        wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::INDIRECT
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC
    } else {
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC
    }
}

/// Creates a buffer of `slot` holding `data` (padded to at least `MIN_BYTES`).
pub fn create_init(device: &wgpu::Device, slot: Slot, data: &[u8]) -> wgpu::Buffer {
    let label = format!("perfuse.{}", slot.name());
    if (data.len() as u64) < MIN_BYTES {
        let mut padded = data.to_vec();
        padded.resize(MIN_BYTES as usize, 0);
        return device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(&label),
            contents: &padded,
            usage: usage(slot),
        });
    }
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(&label),
        contents: data,
        usage: usage(slot),
    })
}

impl SimBuffers {
    /// `init[slot]` are the initial contents of each non-generic slot; `grid_sets` the four
    /// [`super::gpu_types::GridSet`] uniforms; `max_set` the largest set and `cells` the cell count.
    pub fn new(
        device: &wgpu::Device,
        init: Vec<(Slot, Vec<u8>)>,
        grid_sets: [&[u8]; 4],
        max_set: usize,
        cells: usize,
    ) -> SimBuffers {
        let mut by_slot: Vec<Option<wgpu::Buffer>> = (0..=Slot::LAST.binding()).map(|_| None).collect();
        for (slot, data) in init {
            by_slot[slot.binding() as usize] = Some(create_init(device, slot, &data));
        }
        by_slot[Slot::GridCellOf.binding() as usize] =
            Some(create_init(device, Slot::GridCellOf, &vec![0u8; 4 * max_set]));
        by_slot[Slot::GridCursor.binding() as usize] =
            Some(create_init(device, Slot::GridCursor, &vec![0u8; 4 * (cells + 1)]));
        let blocks = cells.div_ceil((super::passes::WORKGROUP * super::passes::SCAN_CHUNK) as usize);
        by_slot[Slot::GridBlockSums.binding() as usize] =
            Some(create_init(device, Slot::GridBlockSums, &vec![0u8; 4 * (blocks + 1)]));
        let gs = |k: usize| create_init(device, Slot::GridSet, grid_sets[k]);
        let grid_set = [gs(0), gs(1), gs(2), gs(3)];
        let backups = STATE_SLOTS
            .iter()
            .filter_map(|s| by_slot[s.binding() as usize].as_ref().map(|b| (*s, b.size())))
            .map(|(s, size)| {
                let b = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(&format!("perfuse.{}_backup", s.name())),
                    size,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                (s, b)
            })
            .collect();
        SimBuffers { by_slot, grid_set, backups }
    }

    /// Device memory held by the simulation buffers (backups included) \[bytes\].
    pub fn memory_bytes(&self) -> u64 {
        let live: u64 = self.by_slot.iter().flatten().map(|b| b.size()).sum();
        let backups: u64 = self.backups.iter().map(|(_, b)| b.size()).sum();
        live + backups + self.grid_set.iter().map(|b| b.size()).sum::<u64>()
    }

    /// The buffer bound at `slot`; grid-generic slots resolve to `grid`'s set (liquid if `None`).
    pub fn get(&self, slot: Slot, grid: Option<GridOf>) -> Option<&wgpu::Buffer> {
        let g = grid.unwrap_or(GridOf::Liquid);
        let resolved = match slot {
            Slot::GridSet => {
                return Some(
                    &self.grid_set[match g {
                        GridOf::Liquid => 0,
                        GridOf::Solid => 1,
                        GridOf::Boundary => 2,
                        GridOf::Ghost => 3,
                    }],
                );
            }
            Slot::GridPos => match g {
                GridOf::Liquid => Slot::LiquidPos,
                GridOf::Solid => Slot::SolidPos,
                GridOf::Boundary => Slot::BoundaryPos,
                GridOf::Ghost => Slot::GhostPos,
            },
            Slot::GridOrder => match g {
                GridOf::Liquid => Slot::LiquidOrder,
                GridOf::Solid => Slot::SolidOrder,
                GridOf::Boundary => Slot::BoundaryOrder,
                GridOf::Ghost => Slot::GhostOrder,
            },
            Slot::GridCellStart => match g {
                GridOf::Liquid => Slot::LiquidCellStart,
                GridOf::Solid => Slot::SolidCellStart,
                GridOf::Boundary => Slot::BoundaryCellStart,
                GridOf::Ghost => Slot::GhostCellStart,
            },
            other => other,
        };
        self.by_slot.get(resolved.binding() as usize).and_then(|b| b.as_ref())
    }

    /// Encodes copies of the evolving buffers into their backups (`restore` = the other way).
    pub fn encode_backup(&self, enc: &mut wgpu::CommandEncoder, restore: bool) {
        for (slot, backup) in &self.backups {
            if let Some(live) = self.get(*slot, None) {
                if restore {
                    enc.copy_buffer_to_buffer(backup, 0, live, 0, live.size());
                } else {
                    enc.copy_buffer_to_buffer(live, 0, backup, 0, live.size());
                }
            }
        }
    }
}

/// Reads `count` elements of `T` from the start of `buffer` (blocking: copy, submit, map, wait).
pub fn read_buffer<T: Pod>(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    buffer: &wgpu::Buffer,
    count: usize,
    what: &str,
) -> Result<Vec<T>, GpuError> {
    let bytes = (count * std::mem::size_of::<T>()) as u64;
    if bytes == 0 {
        return Ok(Vec::new());
    }
    let padded = bytes.div_ceil(wgpu::COPY_BUFFER_ALIGNMENT) * wgpu::COPY_BUFFER_ALIGNMENT;
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("perfuse.readback"),
        size: padded,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("perfuse.readback") });
    enc.copy_buffer_to_buffer(buffer, 0, &staging, 0, padded);
    queue.submit([enc.finish()]);
    map_and_read(device, &staging, bytes, what)
}

/// Maps `staging` (already filled by a submitted copy), waits, and returns its first `bytes` as `T`s.
pub fn map_and_read<T: Pod>(
    device: &wgpu::Device,
    staging: &wgpu::Buffer,
    bytes: u64,
    what: &str,
) -> Result<Vec<T>, GpuError> {
    let slice = staging.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::wait_indefinitely())?;
    rx.recv()
        .map_err(|e| GpuError::Readback { buffer: what.to_string(), message: e.to_string() })?
        .map_err(|e| GpuError::Readback { buffer: what.to_string(), message: e.to_string() })?;
    let out = {
        let view = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Readback { buffer: what.to_string(), message: e.to_string() })?;
        let n = bytes as usize / std::mem::size_of::<T>();
        bytemuck::pod_collect_to_vec::<u8, T>(&view[..n * std::mem::size_of::<T>()])
    };
    staging.unmap();
    Ok(out)
}
