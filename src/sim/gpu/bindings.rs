//! Every GPU resource of the simulation at its fixed binding (STYLE §5.3). All live in group 0 at the
//! numbers declared in `shaders/common.wgsl`; each pass's pipeline layout lists exactly the slots the
//! pass uses (`passes.rs`), so no entry point exceeds the storage-buffer limit though the whole set is
//! larger. `tests/shader_validation.rs` checks every entry point's naga-reflected bindings against the
//! pass table.

/// One resource slot, `binding` = its number in common.wgsl.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Slot {
    Params,
    Step,
    Objects,
    LiquidPos,
    LiquidVel,
    LiquidVelAdv,
    LiquidAcc,
    LiquidAcc0,
    LiquidDens,
    SolidPos,
    SolidVel,
    SolidVelAdv,
    SolidAcc,
    SolidAcc0,
    SolidDisp,
    SolidDens,
    SolidDrho,
    SolidFlags,
    SolidDefGrad,
    SolidStress,
    BondTable,
    BondCount,
    BoundaryPos,
    BoundaryVel,
    BoundaryPos0,
    LiquidOrder,
    LiquidCellStart,
    SolidOrder,
    SolidCellStart,
    BoundaryOrder,
    BoundaryCellStart,
    /// Grid passes: the set being binned (bound per set).
    GridSet,
    GridPos,
    GridOrder,
    GridCellStart,
    GridCellOf,
    GridCursor,
    /// Batched stepping (batch.wgsl): control block and GPU clock, motion table, indirect arguments.
    Batch,
    Motions,
    IndirectArgs,
    /// Squared breaking length of each bond slot (same layout as `BondTable`), compacted with it.
    BondLimit,
    /// Emitters and sinks (emit.wgsl): state, slot positions, slot blocked flags, flow tables.
    EmitState,
    EmitSlots,
    EmitBlocked,
    EmitFlow,
    /// Liquid particle ids (emitters add, sinks compact).
    LiquidId,
    /// Grid passes: per-block cell counts, then block offsets, of the three-phase prefix sum.
    GridBlockSums,
    /// Hourglass control: solid positions in the generated configuration, and the best affine fit F̃
    /// of each particle's bonds (`solid_fit`).
    SolidPosRef,
    SolidAffine,
    /// The moulded beds' heightfields (`sim::bed::BedTable`; static).
    BedTable,
    /// `grid_reorder`: the liquid's live arrays gathered in cell order (`LiquidMove`, 64 bytes each).
    LiquidScratch,
    /// A membrane particle's outward normal in the generated configuration (`SolidSet::normal0`;
    /// static): the capsule's outward normal (`capsule_normal`), which sides its ghosts and seal.
    SolidNormal0,
    /// Each solid particle's bond count in the generated configuration (`SolidSet::bond_count0`;
    /// static): whether a membrane particle still seals (`capsule_seals`).
    BondCount0,
    /// The capsule's ghost sites (`sim::ghosts`, ghosts.wgsl), sorted by owner: static reference (offset
    /// d and owner; masses), placed positions (the ghost grid's positions; w: the owner seals), the
    /// placement's frame (F_o d and m_l; n̂_o and m_s), wall pressure and reaction, the ghost cell list,
    /// each solid particle's first ghost (CSR), and per liquid particle whether it sees a blood ghost.
    GhostRef,
    GhostPos,
    GhostFrame,
    GhostState,
    GhostOrder,
    GhostCellStart,
    GhostStart,
    LiquidSees,
}

impl Slot {
    /// The slot with the highest binding number (sizes the slot table).
    pub const LAST: Slot = Slot::LiquidSees;

    /// Binding number in group 0 (common.wgsl).
    pub const fn binding(self) -> u32 {
        self as u32
    }

    /// `perfuse.<name>` label and WGSL variable name.
    pub const fn name(self) -> &'static str {
        match self {
            Slot::Params => "params",
            Slot::Step => "step",
            Slot::Objects => "objects",
            Slot::LiquidPos => "liquid_pos",
            Slot::LiquidVel => "liquid_vel",
            Slot::LiquidVelAdv => "liquid_vel_adv",
            Slot::LiquidAcc => "liquid_acc",
            Slot::LiquidAcc0 => "liquid_acc0",
            Slot::LiquidDens => "liquid_dens",
            Slot::SolidPos => "solid_pos",
            Slot::SolidVel => "solid_vel",
            Slot::SolidVelAdv => "solid_vel_adv",
            Slot::SolidAcc => "solid_acc",
            Slot::SolidAcc0 => "solid_acc0",
            Slot::SolidDisp => "solid_disp",
            Slot::SolidDens => "solid_dens",
            Slot::SolidDrho => "solid_drho",
            Slot::SolidFlags => "solid_flags",
            Slot::SolidDefGrad => "solid_f",
            Slot::SolidStress => "solid_tau_art",
            Slot::BondTable => "bond_table",
            Slot::BondCount => "bond_count",
            Slot::BoundaryPos => "boundary_pos",
            Slot::BoundaryVel => "boundary_vel",
            Slot::BoundaryPos0 => "boundary_pos0",
            Slot::LiquidOrder => "liquid_order",
            Slot::LiquidCellStart => "liquid_cell_start",
            Slot::SolidOrder => "solid_order",
            Slot::SolidCellStart => "solid_cell_start",
            Slot::BoundaryOrder => "boundary_order",
            Slot::BoundaryCellStart => "boundary_cell_start",
            Slot::GridSet => "grid_set",
            Slot::GridPos => "grid_pos",
            Slot::GridOrder => "grid_order",
            Slot::GridCellStart => "grid_cell_start",
            Slot::GridCellOf => "grid_cell_of",
            Slot::GridCursor => "grid_cursor",
            Slot::Batch => "batch",
            Slot::Motions => "motions",
            Slot::IndirectArgs => "indirect_args",
            Slot::BondLimit => "bond_limit",
            Slot::EmitState => "emit_state",
            Slot::EmitSlots => "emit_slots",
            Slot::EmitBlocked => "emit_blocked",
            Slot::EmitFlow => "emit_flow",
            Slot::LiquidId => "liquid_id",
            Slot::GridBlockSums => "grid_block_sums",
            Slot::SolidPosRef => "solid_pos_ref",
            Slot::SolidAffine => "solid_affine",
            Slot::BedTable => "bed_table",
            Slot::LiquidScratch => "liquid_scratch",
            Slot::SolidNormal0 => "solid_normal0",
            Slot::BondCount0 => "bond_count0",
            Slot::GhostRef => "ghost_ref",
            Slot::GhostPos => "ghost_pos",
            Slot::GhostFrame => "ghost_frame",
            Slot::GhostState => "ghost_state",
            Slot::GhostOrder => "ghost_order",
            Slot::GhostCellStart => "ghost_cell_start",
            Slot::GhostStart => "ghost_start",
            Slot::LiquidSees => "liquid_sees",
        }
    }

    pub const fn is_uniform(self) -> bool {
        matches!(self, Slot::Params | Slot::GridSet)
    }

    /// Layout entry: uniform or read-write storage (common.wgsl declares every storage buffer
    /// `read_write`), visible to compute.
    pub fn layout_entry(self) -> wgpu::BindGroupLayoutEntry {
        let ty = if self.is_uniform() {
            wgpu::BufferBindingType::Uniform
        } else {
            wgpu::BufferBindingType::Storage { read_only: false }
        };
        wgpu::BindGroupLayoutEntry {
            binding: self.binding(),
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        }
    }
}

/// The bind group layout of a pass using `slots`.
pub fn create_layout(device: &wgpu::Device, label: &str, slots: &[Slot]) -> wgpu::BindGroupLayout {
    let entries: Vec<wgpu::BindGroupLayoutEntry> = slots.iter().map(|s| s.layout_entry()).collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binding_numbers_follow_declaration_order() {
        assert_eq!(Slot::Params.binding(), 0);
        assert_eq!(Slot::LiquidDens.binding(), 8);
        assert_eq!(Slot::BondCount.binding(), 21);
        assert_eq!(Slot::BoundaryCellStart.binding(), 30);
        assert_eq!(Slot::GridCursor.binding(), 36);
        assert_eq!(Slot::IndirectArgs.binding(), 39);
        assert_eq!(Slot::BondLimit.binding(), 40);
        assert_eq!(Slot::LiquidId.binding(), 45);
        assert_eq!(Slot::GridBlockSums.binding(), 46);
        assert_eq!(Slot::SolidAffine.binding(), 48);
        assert_eq!(Slot::BedTable.binding(), 49);
        assert_eq!(Slot::LiquidScratch.binding(), 50);
        assert_eq!(Slot::SolidNormal0.binding(), 51);
        assert_eq!(Slot::BondCount0.binding(), 52);
        assert_eq!(Slot::GhostRef.binding(), 53);
        assert_eq!(Slot::LiquidSees.binding(), 60);
    }
}
