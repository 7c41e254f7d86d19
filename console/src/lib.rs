//! The `wheelcal` host console: calibration computations and procedures, reports, the
//! serial client, the virtual board and the diagnose command. The binary is a thin shell
//! over these modules so the host tests drive the same code.

#[allow(missing_docs)] // documented with the link work (issue 14)
pub mod board_cmds;
#[allow(missing_docs)] // documentation under way (issue 15.5)
pub mod calibrate_cmd;
#[allow(missing_docs)] // documentation under way (issue 15.5)
pub mod calibration;
#[allow(missing_docs)] // documentation under way (issue 15.5)
pub mod cli;
#[allow(missing_docs)] // documented with the link work (issue 14)
pub mod client;
pub mod commands;
#[allow(missing_docs)] // documentation under way (issue 15.5)
pub mod demo;
#[allow(missing_docs)] // documentation under way (issue 15.5)
pub mod flash;
#[allow(missing_docs)] // documented with the link work (issue 14)
pub mod link;
#[allow(missing_docs)] // documentation under way (issue 15.5)
pub mod output;
pub mod repl;
#[allow(missing_docs)] // documentation under way (issue 15.5)
pub mod report;
#[allow(missing_docs)] // documentation under way (issue 15.5)
pub mod ros2;
#[allow(missing_docs)] // documentation under way (issue 15.5)
pub mod sim_board;
pub mod stop;
#[allow(missing_docs)] // documented with the link work (issue 14)
pub mod virtual_board;
