//! Measure every preset the way the thesis measured the hardware and print it next to the
//! table: `cargo run -p sim-plant --release --example measure_presets`.

use sim_plant::experiments::{backdrive_test, stiffness_test};
use sim_plant::presets::{preset, preset_names, row};

fn main() {
    for name in preset_names() {
        let model = preset(name).expect("listed preset");
        let r = row(name).expect("listed row");
        let st = stiffness_test(&model, 8.0, 1).expect("stiffness test");
        let bd = backdrive_test(&model, &[0.4, 0.8, 1.6], 1).expect("backdrive test");
        let v = r.viscous();
        println!("{name}");
        println!(
            "  stiffness  table {:>8.0} / {:>8.0}   sim {:>8.0} / {:>8.0}  (+ {:.0}/{:.0}, − {:.0}/{:.0}; knee {:.1}/{:.1})",
            r.stiffness[0], r.stiffness[1], st.k_min(), st.k_max(),
            st.soft[0], st.stiff[0], st.soft[1], st.stiff[1], st.knee[0], st.knee[1]
        );
        println!(
            "  backlash   table {:>8.3}°          sim {:>8.3}°",
            r.backlash_deg,
            st.backlash.to_degrees()
        );
        println!(
            "  stiction   table {:>6.2} / {:>6.2}   sim {:>6.2} / {:>6.2}",
            r.stiction[0], r.stiction[1], bd.stiction[0], bd.stiction[1]
        );
        println!(
            "  coulomb    table {:>6.2} / {:>6.2}   sim {:>6.2} / {:>6.2}",
            r.coulomb[0], r.coulomb[1], bd.coulomb[0], bd.coulomb[1]
        );
        println!(
            "  viscous    table {:>6.3} / {:>6.3}   sim {:>6.3} / {:>6.3}  N·m·s/rad",
            v[0], v[1], bd.viscous[0], bd.viscous[1]
        );
    }
}
