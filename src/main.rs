//! The `parallax` command line (the commands live in the library, `src/lib.rs`).

fn main() {
    parallax::cli_main();
}
