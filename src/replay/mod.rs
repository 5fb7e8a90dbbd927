//! Session recordings (issue 8): the versioned, chunked, checksummed container (`format`) and the
//! recorder and player of sessions (`session`): the scenario plus every command at the step it acts
//! before, with state hashes to verify that a replay is bit-identical; and the viewer's cache of relaxed
//! states (`relaxed_cache`), one-keyframe recordings.

pub mod format;
pub mod relaxed_cache;
pub mod session;
