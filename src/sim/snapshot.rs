//! Keyframes of a running simulation (issue 8): everything that evolves — particles, bonds, the
//! reference configuration, boundary objects and their motions, emitter accounts, clock, gravity and
//! damping — captured so that restoring it and stepping on gives bit for bit the states a run that
//! never stopped gives, on the back-end (and adapter) that took it. Replay seeks with them
//! (`replay::session::Player`) and a take-over branch starts from one.
//!
//! Each back-end captures its own representation: the CPU twin its whole `CpuState`, the GPU its
//! state buffers byte for byte plus the host's mirror of them. A snapshot therefore restores only
//! into the same back-end kind, built from the same scenario; each back-end checks the sizes ([`check_eq`])
//! and refuses a snapshot that does not fit, with a message that says so.

use super::RunStats;
use serde::{Deserialize, Serialize};

/// Layout version of the encoded snapshot: bumped whenever `CpuState` or the GPU's state buffers
/// change, so that a keyframe of another build is refused instead of misread. 2: boundary objects carry
/// their solid contact (`BoundaryObject::friction`, `ObjectGpu`/`MotionGpu.friction`). 3: the suction's
/// valve (`CpuState::suction_held`, the GPU mirror's `suction_held`; `Command::SetSuction`). 4: the GPU
/// keeps τ and R as their upper triangles (`StressGpu`, 48 bytes per solid particle instead of 96).
/// 5: boundary particles carry the solid-equivalent mass they show the liquid's nˢ (`BoundarySet::m_sn`;
/// the GPU's object word its `BOUNDARY_IN_TISSUE` bit). 6: solid particles carry the capsule's generated
/// outward normal (`SolidSet::normal0`).
pub const SNAPSHOT_LAYOUT: u32 = 6;

/// One keyframe of a simulation.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Snapshot {
    pub layout: u32,
    /// `Simulation::backend_name` of the simulation that took it (the adapter, for the record).
    pub engine: String,
    pub t: f64,
    pub steps: u64,
    /// The run statistics at the time (so that `summary.json` of a resumed run counts every step).
    pub stats: RunStats,
    pub data: EngineSnapshot,
}

/// The back-end's own state.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub enum EngineSnapshot {
    Cpu(Box<super::cpu::CpuSnapshot>),
    Gpu(Box<super::gpu::GpuSnapshot>),
}

/// Why a snapshot could not be decoded or restored.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SnapshotError {
    #[error("keyframe does not decode: {0}")]
    Decode(String),
    #[error("keyframe was written with state layout {found}, this build reads layout {SNAPSHOT_LAYOUT}")]
    Layout { found: u32 },
    #[error("keyframe of the {found} back-end cannot be restored into the {want} back-end")]
    Backend { found: &'static str, want: &'static str },
    #[error("keyframe does not fit this simulation: {0} (was it taken from another scenario?)")]
    Mismatch(String),
}

impl EngineSnapshot {
    pub fn kind(&self) -> &'static str {
        match self {
            EngineSnapshot::Cpu(_) => "CPU",
            EngineSnapshot::Gpu(_) => "GPU",
        }
    }
}

impl Snapshot {
    /// Compact binary encoding (postcard); the recording compresses it.
    pub fn encode(&self) -> Vec<u8> {
        // Serialising plain data into a Vec cannot fail; an empty payload would be refused on decode.
        postcard::to_stdvec(self).unwrap_or_default()
    }

    pub fn decode(bytes: &[u8]) -> Result<Snapshot, SnapshotError> {
        decode_checked(bytes)
    }
}

/// Decodes a value whose encoding leads with a snapshot's `layout` (a `Snapshot`, or a replay keyframe
/// that starts with one). The layout is read first, so another build's keyframe is named as such
/// rather than failing somewhere inside the state.
pub fn decode_checked<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, SnapshotError> {
    let (layout, _) = postcard::take_from_bytes::<u32>(bytes).map_err(|e| SnapshotError::Decode(e.to_string()))?;
    if layout != SNAPSHOT_LAYOUT {
        return Err(SnapshotError::Layout { found: layout });
    }
    postcard::from_bytes(bytes).map_err(|e| SnapshotError::Decode(e.to_string()))
}

/// `what` must be equal in the snapshot and the simulation.
pub fn check_eq<T: PartialEq + std::fmt::Debug>(what: &str, snap: T, sim: T) -> Result<(), SnapshotError> {
    if snap == sim {
        Ok(())
    } else {
        Err(SnapshotError::Mismatch(format!("{what}: {snap:?} in the keyframe, {sim:?} in the simulation")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A keyframe of another layout is refused by its layout number, even when its state no longer
    /// decodes under this build's types.
    #[test]
    fn another_layout_is_named_before_its_state_is_decoded() {
        let mut bytes = postcard::to_stdvec(&(SNAPSHOT_LAYOUT - 1)).expect("encode");
        bytes.extend_from_slice(&[0xff; 16]);
        match Snapshot::decode(&bytes) {
            Err(SnapshotError::Layout { found }) => assert_eq!(found, SNAPSHOT_LAYOUT - 1),
            other => panic!("expected a layout error, got {other:?}"),
        }
    }
}
