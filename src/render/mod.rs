//! What the surgeon sees: the camera, the renderer of tissue (lit sphere impostors coloured by a
//! field), blood (screen-space fluid rendering) and boundary objects (tools, walls), and offscreen
//! targets with PNG capture. The renderer draws a published particle set (`sim::frame`) and never
//! touches the simulation (DESIGN: data flows one way).

pub mod camera;
pub mod gpu_data;
pub mod offscreen;
pub mod renderer;
pub mod snapshot;
pub mod timer;

pub use camera::OrbitCamera;
pub use gpu_data::FieldMode;
pub use offscreen::Offscreen;
pub use renderer::{RenderError, RenderSettings, Renderer, Scene};
