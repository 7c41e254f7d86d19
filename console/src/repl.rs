//! `wheelcal console`: an interactive prompt for people at a bench. Each line is a
//! wheelcal command without the program name (`info`, `factors get`, `run umbmark --dir
//! cw --side 2`, ...), run on one open connection; history is kept in
//! `~/.wheelcal_history` and Tab completes command names.

use crate::args::{Cli, Command};
use crate::session::Ctx;
use anyhow::Result;
use clap::{CommandFactory, Parser};
use rustyline::completion::{Completer, Pair};
use rustyline::error::ReadlineError;
use rustyline::highlight::Highlighter;
use rustyline::hint::Hinter;
use rustyline::validate::Validator;
use rustyline::{Editor, Helper};

/// Completes the first word from the command list, the second from the command's
/// subcommands and flags, and later words from the flags of the (sub)command typed so
/// far only; a completed word gets its trailing space, as a shell does.
struct Completion {
    root: clap::Command,
}

impl Completion {
    fn new() -> Self {
        Completion {
            root: Cli::command(),
        }
    }

    /// Candidates for the word after `typed` (the words before it).
    fn candidates(&self, typed: &[&str]) -> Vec<String> {
        let hidden = |c: &clap::Command| matches!(c.get_name(), "console" | "sim-board" | "demo");
        let Some((first, rest)) = typed.split_first() else {
            return self
                .root
                .get_subcommands()
                .filter(|c| !hidden(c))
                .map(|c| c.get_name().to_string())
                .chain(["help".to_string(), "quit".to_string()])
                .collect();
        };
        let Some(mut cmd) = self.root.find_subcommand(first).filter(|c| !hidden(c)) else {
            return Vec::new();
        };
        // Descend through the subcommands typed (`factors set`, `run umbmark`).
        let mut descended = false;
        for w in rest {
            if let Some(sub) = cmd.find_subcommand(w) {
                cmd = sub;
                descended = true;
            }
        }
        let mut out: Vec<String> = Vec::new();
        if !descended && rest.iter().all(|w| w.starts_with('-')) {
            out.extend(cmd.get_subcommands().map(|s| s.get_name().to_string()));
        }
        out.extend(
            cmd.get_arguments()
                .filter(|a| !a.is_global_set() && !a.is_hide_set())
                .filter_map(|a| a.get_long().map(|l| format!("--{l}"))),
        );
        out
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
        let typed: Vec<&str> = head[..start].split_whitespace().collect();
        let mut out: Vec<Pair> = self
            .candidates(&typed)
            .into_iter()
            .filter(|w| w.starts_with(word))
            .map(|w| Pair {
                replacement: format!("{w} "),
                display: w,
            })
            .collect();
        out.sort_by(|a, b| a.display.cmp(&b.display));
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

/// Runs one parsed command line on the session: the dispatcher, passed in by the caller
/// so this module does not depend on it (it is the dispatcher that runs the console).
pub type RunCommand = fn(Cli, &mut Ctx) -> Result<()>;

/// Runs the prompt until `quit` or end of input; each line goes to `run_command`.
pub fn run(ctx: &mut Ctx, json: bool, run_command: RunCommand) -> Result<()> {
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
                        if matches!(cli.command, Command::Console) {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn complete(line: &str) -> Vec<String> {
        let h = rustyline::history::DefaultHistory::new();
        let ctx = rustyline::Context::new(&h);
        let (_, pairs) = Completion::new()
            .complete(line, line.len(), &ctx)
            .expect("completes");
        pairs.into_iter().map(|p| p.replacement).collect()
    }

    /// Issue 13 polish: a completed word gets its space, so the next Tab goes on.
    #[test]
    fn completion_adds_the_space() {
        assert_eq!(complete("fac"), ["factors "]);
        assert_eq!(complete("factors s"), ["save ", "set "]);
    }

    /// Issue 13 polish: only the typed command's own flags, not other commands'.
    #[test]
    fn completion_offers_only_the_commands_own_flags() {
        let run_umbmark = complete("run umbmark --");
        for f in [
            "--dir ",
            "--side ",
            "--log-rate ",
            "--no-wait ",
            "--link-timeout ",
            "--no-link-failsafe ",
        ] {
            assert!(
                run_umbmark.contains(&f.to_string()),
                "{f} in {run_umbmark:?}"
            );
        }
        assert!(
            !run_umbmark.contains(&"--length ".to_string()),
            "{run_umbmark:?}"
        );
        assert!(
            !run_umbmark.contains(&"--path ".to_string()),
            "{run_umbmark:?}"
        );
        let set = complete("factors set --");
        assert!(set.contains(&"--f-lat ".to_string()), "{set:?}");
        assert!(!set.contains(&"--ros2 ".to_string()), "{set:?}");
        assert!(
            !set.contains(&"--port ".to_string()),
            "global flags: {set:?}"
        );
        assert_eq!(complete("drive --v"), ["--vx ", "--vy "]);
        assert!(complete("sim-board --").is_empty());
    }
}
