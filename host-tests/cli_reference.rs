//! `docs/cli.md` is what the command-line definitions say: every command and option, as
//! `unlag help COMMAND` prints them. `UNLAG_BLESS=1 cargo test --test cli_reference` writes
//! it again after a change to the commands.

use std::path::Path;

#[test]
fn docs_cli_md_matches_the_command_line_definitions() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/cli.md");
    let rendered = unlag::cli::reference::markdown();
    if std::env::var_os("UNLAG_BLESS").is_some() {
        std::fs::write(&path, &rendered).expect("write docs/cli.md");
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    if committed != rendered {
        let line = committed
            .lines()
            .zip(rendered.lines())
            .position(|(a, b)| a != b)
            .map_or_else(
                || committed.lines().count().min(rendered.lines().count()) + 1,
                |i| i + 1,
            );
        panic!(
            "docs/cli.md is out of date with the command-line definitions (first difference at \
             line {line}): run `UNLAG_BLESS=1 cargo test --test cli_reference` and commit it"
        );
    }
}
