// Shared by the build scripts of every crate whose binaries or tests may link MuJoCo (sim,
// trainer, firmware-sim, tests), through `include!`: with the crate's `mujoco` feature on, its
// executables get the folder of libmujoco.so (MUJOCO_DYNAMIC_LINK_DIR, which .cargo/config.toml
// sets to .mujoco/lib) as their run-time search path, so they find the library without
// LD_LIBRARY_PATH. `cargo::rustc-link-arg` reaches only the crate's own binaries and tests,
// hence one call per crate.
fn mujoco_rpath() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    if std::env::var_os("CARGO_FEATURE_MUJOCO").is_none() {
        return;
    }
    match std::env::var("MUJOCO_DYNAMIC_LINK_DIR") {
        Ok(dir) if std::path::Path::new(&dir).join("libmujoco.so").exists() => {
            println!("cargo::rustc-link-arg=-Wl,-rpath,{dir}");
        }
        Ok(dir) => println!(
            "cargo::warning=no libmujoco.so in {dir}: run scripts/fetch-mujoco.sh before building with --features mujoco"
        ),
        Err(_) => println!(
            "cargo::warning=MUJOCO_DYNAMIC_LINK_DIR is not set (.cargo/config.toml sets it): the binaries will need LD_LIBRARY_PATH to find libmujoco.so"
        ),
    }
}
