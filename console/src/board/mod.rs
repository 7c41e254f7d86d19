//! The board commands (`info`, `factors`, `robot`, `drive`, `run`, `status`, `log`, `stop`), as
//! functions over any [`Client`](crate::client::Client) so the tests drive them through
//! an in-memory link. One file per concern; everything is re-exported here, so callers
//! write `board::pull_trial` whichever file holds it.

pub mod apply;
pub mod factors;
pub mod geometry;
pub mod info;
pub mod programs;
pub mod trial_log;

pub use apply::{apply_settings, Settings, Target};
pub use factors::{factors_text, merge_corrections, FactorsView, GivenFactors};
pub use geometry::{with_robot, RobotView};
pub use info::{info, status_line, stored_word, InfoReport};
pub use programs::{
    drive_for, eviction_forecast, program_time_limit, run_circle, run_omni, run_umbmark,
    start_program, stop_after_interrupt, wait_program,
};
pub use trial_log::{
    program_text, pull_trial, records_to_csv, trial_end_text, trial_list, PulledTrial, TrialList,
    TrialRow,
};
