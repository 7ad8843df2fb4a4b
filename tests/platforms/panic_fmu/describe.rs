//! Prints the model description of the `PanicTest` FMU (the driver's scenario needs its GUID).

#[path = "model.rs"]
mod model;

use spurio_fmi2::{Config, FmuModel};

fn main() -> Result<(), String> {
    print!("{}", model::PanicTest::describe(&Config::new())?.to_xml());
    Ok(())
}
