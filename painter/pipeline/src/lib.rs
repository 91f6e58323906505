//! Octopaint's real-time pipeline (docs/architecture.md; the paper's
//! section 5 and Fig. 4): the engine under every front end. A stroke thread
//! owns the document and paints it, a staging thread copies what changed,
//! and the front end's frame loop (the window's, the headset's, the
//! benchmark's render thread) uploads the copies and casts, with bounded
//! queues between them, so that painting never waits for rendering and
//! rendering never waits for painting, and a ledger that measures each
//! job's stroke-to-display latency exactly.
//!
//! | module | what it holds |
//! | --- | --- |
//! | [`jobs`] | jobs and questions for the stroke thread, their queue |
//! | [`canvas`] | what the stroke thread paints: the `Canvas` trait, bare documents (`Replay`), the status |
//! | [`document`] | an open document (journal, saves) as a canvas |
//! | [`engine`] | the stroke and staging threads, publications, the layer list |
//! | [`staging`] | the pending set of dirty blocks, staging buffers, the stack of staged copies |
//! | [`layout`] | each layer's range of the GPU's pages |
//! | [`frames`] | a front end's frame: uploads, layer ranges, g3 per layer, the layer table |
//! | [`ledger`] | publications, uploads, the consistent cut, per-job latency |
//! | [`settings`] | block size, blocks per frame, mask size, strategies |
//! | [`pipeline`] | the headless front end: the engine with a render thread of its own |
//! | [`play`] | a trace fed to a front end at its pace; a test's hold on the stroke thread |
//! | [`view`] | what a front end's frame casts: dynamic resolution, still frames, the frame log and statistics, the heavy-operation indicator |

pub mod canvas;
pub mod document;
pub mod engine;
pub mod frames;
pub mod jobs;
pub mod layout;
pub mod ledger;
pub mod pipeline;
pub mod play;
pub mod settings;
pub mod staging;
pub mod view;

pub use canvas::{Canvas, LayerRow, Ran, Replay, Status};
pub use document::OpenDocument;
pub use engine::{Busy, Engine, Finished, Gate, Hooks, StagingRecord, Submitter};
pub use frames::{Frames, Prepared};
pub use jobs::{Aim, Job, SubmitError, Ticket};
pub use pipeline::{FrameRecord, Pipeline, PipelineError, Report};
pub use settings::{BlockSize, MaskSize, Settings, Strategy};
pub use view::{Doing, FrameStats, Indicator, Pace, Planned, View};
