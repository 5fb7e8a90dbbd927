//! Session recordings (issue 8): the versioned, chunked, checksummed container (`format`). The
//! recorder and player that fill it with the viewer's command stream and state keyframes build on it.

pub mod format;
