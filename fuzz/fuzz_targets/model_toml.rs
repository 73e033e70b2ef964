//! Fuzz the model TOML parser (sim-plant's `model`): any text must parse to a model or give a
//! located error, never a panic; a model that parses must write itself back
//! (`to_toml_string`, what `--save-model` writes) as a file that parses to an equal model.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sim_plant::model::Model;

fuzz_target!(|input: &[u8]| {
    let Ok(text) = std::str::from_utf8(input) else {
        return;
    };
    let Ok(model) = Model::from_toml_str(text, "fuzz.toml") else {
        return;
    };
    let written = model.to_toml_string();
    let again = Model::from_toml_str(&written, "written.toml")
        .unwrap_or_else(|e| panic!("a parsed model wrote a file that fails: {e}\n{written}"));
    assert_eq!(
        again, model,
        "the written file parses to another model:\n{written}"
    );
});
