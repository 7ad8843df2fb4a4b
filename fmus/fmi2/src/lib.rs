//! FMI 2.0 CS export layer.
