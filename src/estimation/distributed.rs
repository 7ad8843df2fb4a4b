//! placeholder
pub struct DistributedObserver;
pub struct DistributedObserverConfig;
pub enum ObserverDesign {
    LqDesign,
    LocalKalman,
}
