//! The command-line reference (`docs/cli.md`), generated from the clap definitions so that it
//! cannot go stale: a test compares the file with what this module renders.

use clap::CommandFactory as _;

/// Width the help texts are wrapped at in the reference.
const WIDTH: usize = 100;

/// `docs/cli.md`: every command with every option, as `unlag help COMMAND` prints them.
#[must_use]
pub fn markdown() -> String {
    let mut cmd = super::Cli::command()
        .term_width(WIDTH)
        .max_term_width(WIDTH);
    cmd.build();
    let mut out = String::from(
        "# Command-line reference\n\n\
         Every `unlag` command with every option, as `unlag help COMMAND` (or `unlag COMMAND \
         --help`) prints it. This file is generated from the command-line definitions \
         (`src/cli/`); `cargo test --test cli_reference` fails when it is out of date, and \
         `UNLAG_BLESS=1 cargo test --test cli_reference` writes it again.\n\n",
    );
    out.push_str("## Commands\n\n| command | what it does |\n|---|---|\n");
    for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
        let about = sub
            .get_about()
            .map(|a| a.to_string())
            .unwrap_or_default()
            .replace('|', "\\|");
        let name = sub.get_name();
        out.push_str(&format!("| [`unlag {name}`](#unlag-{name}) | {about} |\n"));
    }
    out.push_str("\n## `unlag`\n\n```text\n");
    out.push_str(cmd.render_long_help().to_string().trim_end());
    out.push_str("\n```\n");
    for sub in cmd.get_subcommands_mut().filter(|s| !s.is_hide_set()) {
        let name = sub.get_name().to_string();
        out.push_str(&format!("\n## `unlag {name}`\n\n```text\n"));
        out.push_str(sub.render_long_help().to_string().trim_end());
        out.push_str("\n```\n");
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_command_and_option_is_in_the_reference() {
        use clap::CommandFactory as _;
        let text = super::markdown();
        let cmd = crate::cli::Cli::command();
        for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
            assert!(
                text.contains(&format!("## `unlag {}`", sub.get_name())),
                "{}",
                sub.get_name()
            );
            for arg in sub.get_arguments().filter(|a| !a.is_hide_set()) {
                if let Some(long) = arg.get_long() {
                    assert!(text.contains(&format!("--{long}")), "{long}");
                }
            }
        }
    }
}
