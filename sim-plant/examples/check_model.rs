//! Parse model files and print the parsed model or the error:
//! `cargo run -p sim-plant --example check_model -- FILE...`.
fn main() {
    for path in std::env::args().skip(1) {
        match sim_plant::Model::load(&path) {
            Ok(m) => print!("{}", m.to_toml_string()),
            Err(e) => println!("error: {e}"),
        }
    }
}
