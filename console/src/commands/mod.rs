//! One module per command: `cli::run` only dispatches here, so a new command is a new
//! module and one match arm. The modules take their arguments from [`crate::args`] and
//! the connection from [`crate::session`], never from the dispatcher.

pub mod apply;
pub mod board;
pub mod calibrate;
pub mod diagnose;
pub mod evaluate;
pub mod factors;
pub mod import;
pub mod log;
pub mod omni;
pub mod procedure;
pub mod program;
pub mod robot;
pub mod sim;
pub mod umbmark;
