//! What the user sees on standard error: progress bars (files and iterations) when it is a
//! terminal, plain log lines otherwise; `--quiet` keeps only errors, `--verbose` adds detail.

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::fmt::Display;
use std::io::IsTerminal;
use std::io::Write;
use std::time::Duration;

/// How much to print.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verbosity {
    /// Errors only.
    Quiet,
    /// Errors, warnings, one line per file, summaries.
    Normal,
    /// Also parameters, skipped files, per-iteration figures.
    Verbose,
}

/// The standard-error side of a run. Shared by the worker threads of a batch.
pub struct Ui {
    verbosity: Verbosity,
    bars: Option<MultiProgress>,
}

impl Ui {
    /// Bars only on a terminal and when not quiet; `FOLDMATCH_NO_PROGRESS` set (to anything)
    /// turns them off.
    pub fn new(verbosity: Verbosity) -> Self {
        let interactive = std::io::stderr().is_terminal()
            && verbosity > Verbosity::Quiet
            && std::env::var_os("FOLDMATCH_NO_PROGRESS").is_none();
        let bars =
            interactive.then(|| MultiProgress::with_draw_target(ProgressDrawTarget::stderr()));
        Self { verbosity, bars }
    }

    /// Whether progress bars are drawn (a terminal).
    pub fn has_bars(&self) -> bool {
        self.bars.is_some()
    }

    /// The verbosity.
    pub fn verbosity(&self) -> Verbosity {
        self.verbosity
    }

    fn line(&self, text: &str) {
        // A closed stderr (a pipe whose reader quit: `foldmatch batch ... 2>&1 | head`) loses
        // the line; `eprintln!` would panic.
        let write = || {
            let _ = writeln!(std::io::stderr().lock(), "{text}");
        };
        match &self.bars {
            Some(multi) => multi.suspend(write),
            None => write(),
        }
    }

    /// A normal line (not with `--quiet`).
    pub fn info(&self, msg: impl Display) {
        if self.verbosity >= Verbosity::Normal {
            self.line(&msg.to_string());
        }
    }

    /// A detail line (only with `--verbose`).
    pub fn detail(&self, msg: impl Display) {
        if self.verbosity >= Verbosity::Verbose {
            self.line(&msg.to_string());
        }
    }

    /// A warning (not with `--quiet`).
    pub fn warn(&self, msg: impl Display) {
        if self.verbosity >= Verbosity::Normal {
            self.line(&format!("warning: {msg}"));
        }
    }

    /// An error (always printed).
    pub fn error(&self, msg: impl Display) {
        self.line(&format!("error: {msg}"));
    }

    /// A bar counting files (hidden without a terminal).
    pub fn files_bar(&self, total: usize) -> Bar {
        self.bar(
            total,
            "{prefix:>9} [{bar:32.green/white}] {pos}/{len} files, {elapsed} (ETA {eta}) {msg}",
            "files",
            true,
        )
    }

    /// A bar counting the iterations of one fit (hidden without a terminal).
    pub fn iterations_bar(&self, name: &str, total: usize) -> Bar {
        let mut short: String = name
            .chars()
            .rev()
            .take(24)
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        if short.len() < name.len() {
            short = format!("…{short}");
        }
        self.bar(
            total,
            "{prefix:>25} [{bar:32.cyan/blue}] {pos}/{len} it {msg}",
            &short,
            false,
        )
    }

    fn bar(&self, total: usize, template: &str, prefix: &str, at_end: bool) -> Bar {
        let Some(multi) = &self.bars else {
            return Bar(None);
        };
        let style = ProgressStyle::with_template(template)
            .expect("valid template")
            .progress_chars("=> ");
        let pb = ProgressBar::new(total as u64)
            .with_style(style)
            .with_prefix(prefix.to_string());
        let pb = if at_end {
            multi.add(pb)
        } else {
            multi.insert(0, pb)
        };
        pb.enable_steady_tick(Duration::from_millis(200));
        Bar(Some((pb, multi.clone())))
    }
}

/// A progress bar, or nothing when not on a terminal.
pub struct Bar(Option<(ProgressBar, MultiProgress)>);

impl Bar {
    /// Sets the position.
    pub fn set(&self, position: usize) {
        if let Some((pb, _)) = &self.0 {
            pb.set_position(position as u64);
        }
    }

    /// Advances by one.
    pub fn inc(&self) {
        if let Some((pb, _)) = &self.0 {
            pb.inc(1);
        }
    }

    /// Sets the trailing message.
    pub fn message(&self, msg: impl Display) {
        if let Some((pb, _)) = &self.0 {
            pb.set_message(msg.to_string());
        }
    }

    /// Removes the bar from the screen.
    pub fn finish(&self) {
        if let Some((pb, multi)) = &self.0 {
            pb.finish_and_clear();
            multi.remove(pb);
        }
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.finish();
    }
}
