//! Octopaint's real-time pipeline (docs/architecture.md; the paper's
//! section 5 and Fig. 4): a stroke thread, a staging thread and a render
//! thread, with bounded queues between them, so that painting never waits
//! for rendering and rendering never waits for painting, and a ledger that
//! measures each job's stroke-to-display latency exactly.
//!
//! | module | what it holds |
//! | --- | --- |
//! | [`jobs`] | the stroke job queue |
//! | [`staging`] | the pending set of dirty blocks, staging buffers, the stack of staged copies |
//! | [`ledger`] | publications, uploads, the consistent cut, per-job latency |
//! | [`settings`] | block size, blocks per frame, mask size, strategies |
//! | [`pipeline`] | the three threads |

pub mod jobs;
pub mod ledger;
pub mod pipeline;
pub mod settings;
pub mod staging;

pub use jobs::{Job, SubmitError, Ticket};
pub use pipeline::{FrameRecord, Gate, Hooks, Pipeline, PipelineError, Report, StagingRecord};
pub use settings::{BlockSize, MaskSize, Settings, Strategy};
