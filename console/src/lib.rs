//! The `wheelcal` host console: calibration computations and procedures, reports, the
//! serial client, the virtual board and the diagnose command. The binary is a thin shell
//! over these modules so the host tests drive the same code.

pub mod args;
pub mod board;
pub mod calibration;
pub mod cli;
pub mod client;
pub mod commands;
pub mod demo;
pub mod flash;
pub mod foxglove_live;
pub mod input;
pub mod link;
pub mod mcap_out;
pub mod output;
pub mod progress;
pub mod recordings;
pub mod repl;
pub mod report;
pub mod ros2;
pub mod session;
pub mod sim_board;
pub mod stop;
pub mod tum;
pub mod virtual_board;
