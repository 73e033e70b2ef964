//! `hil-host` command-line interface.
fn main() {
    println!("hil-host: see --help");
}
