//! Prints the model description of the `PanicTest` FMU (the driver's scenario needs its GUID).

#[path = "model.rs"]
mod model;

use spurio_export::{Config, FmuModel};

fn main() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    print!("{}", model::PanicTest::describe(&Config::new())?.to_xml());
    Ok(())
}
