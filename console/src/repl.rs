//! `wheelcal console`: an interactive prompt for people at a bench. Each line is a
//! wheelcal command without the program name (`info`, `factors get`, `run umbmark --dir
//! cw --side 2`, ...), run on one open connection; history is kept in
//! `~/.wheelcal_history` and Tab completes command names.

use crate::cli::{run as run_command, Cli, Ctx};
use anyhow::Result;
use clap::{CommandFactory, Parser};
use rustyline::completion::{Completer, Pair};
use rustyline::error::ReadlineError;
use rustyline::highlight::Highlighter;
use rustyline::hint::Hinter;
use rustyline::validate::Validator;
use rustyline::{Editor, Helper};

/// Completes the first word from the command list and later words from each command's
/// subcommands and flags.
struct Completion {
    words: Vec<(String, Vec<String>)>,
}

impl Completion {
    fn new() -> Self {
        let cmd = Cli::command();
        let words = cmd
            .get_subcommands()
            .filter(|c| !matches!(c.get_name(), "console" | "sim-board" | "demo"))
            .map(|c| {
                let mut follow: Vec<String> = c
                    .get_subcommands()
                    .map(|s| s.get_name().to_string())
                    .collect();
                follow.extend(
                    c.get_arguments()
                        .filter_map(|a| a.get_long().map(|l| format!("--{l}"))),
                );
                for s in c.get_subcommands() {
                    follow.extend(
                        s.get_arguments()
                            .filter_map(|a| a.get_long().map(|l| format!("--{l}"))),
                    );
                }
                (c.get_name().to_string(), follow)
            })
            .collect();
        Completion { words }
    }
}

impl Completer for Completion {
    type Candidate = Pair;
    fn complete(
        &self,
        line: &str,
        pos: usize,
        _: &rustyline::Context<'_>,
    ) -> rustyline::Result<(usize, Vec<Pair>)> {
        let head = &line[..pos];
        let start = head.rfind(' ').map_or(0, |i| i + 1);
        let word = &head[start..];
        let first = head.split_whitespace().next().unwrap_or("");
        let pool: Vec<String> = if start == 0 {
            self.words
                .iter()
                .map(|(w, _)| w.clone())
                .chain(["help".to_string(), "quit".to_string()])
                .collect()
        } else {
            self.words
                .iter()
                .find(|(w, _)| w == first)
                .map(|(_, f)| f.clone())
                .unwrap_or_default()
        };
        let mut out: Vec<Pair> = pool
            .into_iter()
            .filter(|w| w.starts_with(word))
            .map(|w| Pair {
                display: w.clone(),
                replacement: w,
            })
            .collect();
        out.dedup_by(|a, b| a.display == b.display);
        Ok((start, out))
    }
}

impl Hinter for Completion {
    type Hint = String;
}
impl Highlighter for Completion {}
impl Validator for Completion {}
impl Helper for Completion {}

/// Runs the prompt until `quit` or end of input.
pub fn run(ctx: &mut Ctx, json: bool) -> Result<()> {
    let mut rl: Editor<Completion, rustyline::history::DefaultHistory> = Editor::new()?;
    rl.set_helper(Some(Completion::new()));
    let history =
        std::env::var_os("HOME").map(|h| std::path::PathBuf::from(h).join(".wheelcal_history"));
    if let Some(h) = &history {
        let _ = rl.load_history(h);
    }
    eprintln!("wheelcal console: type a command (`help` lists them, Tab completes, `quit` leaves)");
    let mut failed = 0usize;
    loop {
        let prompt = format!("wheelcal {}> ", ctx.port.as_deref().unwrap_or("(no port)"));
        match rl.readline(&prompt) {
            Ok(line) => {
                let line = line.trim();
                if line.is_empty() {
                    continue;
                }
                let _ = rl.add_history_entry(line);
                if matches!(line, "quit" | "exit") {
                    break;
                }
                let words = match shell_words::split(line) {
                    Ok(w) => w,
                    Err(e) => {
                        eprintln!("error: {e}");
                        continue;
                    }
                };
                let mut argv = vec!["wheelcal".to_string()];
                if json {
                    argv.push("--json".into());
                }
                argv.extend(words);
                match Cli::try_parse_from(&argv) {
                    Ok(cli) => {
                        if matches!(cli.command, crate::cli::Command::Console) {
                            eprintln!("already in the console");
                            continue;
                        }
                        match run_command(cli, ctx) {
                            Ok(()) => {}
                            // Ctrl-C stopped the robot; back to the prompt.
                            Err(e) if e.is::<crate::stop::Interrupted>() => eprintln!("{e}"),
                            Err(e) => {
                                failed += 1;
                                eprintln!("error: {e:#}");
                            }
                        }
                    }
                    Err(e) => {
                        if e.use_stderr() {
                            failed += 1;
                        }
                        let _ = e.print();
                    }
                }
            }
            Err(ReadlineError::Interrupted) => continue,
            Err(ReadlineError::Eof) => break,
            Err(e) => return Err(e.into()),
        }
    }
    if let Some(h) = &history {
        let _ = rl.save_history(h);
    }
    // Piped input (a script): a failed command makes the whole run fail, as a shell
    // script with `set -e` would expect; at a terminal the person saw each error.
    use std::io::IsTerminal;
    if failed > 0 && !std::io::stdin().is_terminal() {
        anyhow::bail!("{failed} command(s) failed");
    }
    Ok(())
}
