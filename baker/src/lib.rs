//! snerf-baker: turns a trained field into a baked asset (sparse grid + view MLP) and glTF.
//!
//! Data flow (planned, issue 4): trainer checkpoint -> dense evaluation on a fine grid in the
//! (contracted) scene box -> keep occupied, visible blocks -> quantize -> `snerf-asset` file.
//! Nothing is implemented here yet; the `snerf` command has no bake subcommand until it is.
