//! What every instance of one configuration of a model shares, built once per configuration
//! and process ([`interface`]): the model description, the access table of the get/set
//! checks, the runs of values a model call may write (the roll-back's and the finiteness
//! scan's), and the FMI 3.0 arrays over the table.

use super::access::Access;
use crate::description::arrays::Layout;
use crate::description::{Config, ModelInfo};
use crate::model::{Cause, FmuModel};
use crate::values::computed_runs;
use crate::variables::VariableType;
use std::any::TypeId;
use std::sync::{Arc, Mutex};

/// What every instance of one configuration of a model shares, built once per configuration
/// ([`interface`]): the model description, the access table that get/set calls check values
/// against (value reference = index), the variables a model call may change, and the FMI
/// 3.0 arrays over the table.
#[derive(Debug)]
pub struct Interface {
    /// The model description.
    pub info: ModelInfo,
    /// How each variable may be accessed, by value reference.
    pub access: Vec<Access>,
    /// The variables a model call may write, as runs of indices
    /// ([`crate::values::computed_runs`]): what is copied before the call and checked for
    /// non-finite values after it (a `memcpy` and a branch-free scan a run). Parameters and
    /// inputs a run spans are copied and scanned too: the model does not change them
    /// (checked in debug builds), and what the master sets is finite.
    pub computed: Vec<std::ops::Range<usize>>,
    /// Whether a String is in a run (the texts are then copied too).
    pub computed_texts: bool,
    /// When the model computes one run of at most [`WINDOW`] values (a scalar filter's
    /// outputs): the [`WINDOW`] consecutive values that hold it, copied and scanned as a fixed
    /// block instead of the run.
    pub window: Option<Window>,
    /// The FMI 3.0 variables (arrays) over the table.
    pub layout: Layout,
    /// By FMI 3.0 value reference: the scalars it names, for the get/set fast path.
    pub spans: Vec<Span>,
}

/// The number of values of a [`Window`].
pub const WINDOW: usize = 4;

/// [`WINDOW`] consecutive values from `start` that hold the one run of computed values:
/// `lanes[k]` says whether value `start + k` is in the run (the others, parameters or inputs,
/// are copied with it and otherwise ignored).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    /// The index of the first value.
    pub start: usize,
    /// Which of the values belong to the run.
    pub lanes: [bool; WINDOW],
    /// The lanes as bit masks (all ones in the run, zero outside), for the branch-free scan.
    pub(crate) keep: [u64; WINDOW],
}

impl Window {
    /// The window of `computed` in a table of `len` values: `Some` when `computed` is one
    /// run of at most [`WINDOW`] values and the table holds at least [`WINDOW`].
    pub fn of(computed: &[std::ops::Range<usize>], len: usize) -> Option<Self> {
        let [run] = computed else { return None };
        if run.is_empty() || run.len() > WINDOW || len < WINDOW || run.end > len {
            return None;
        }
        let start = run.start.min(len - WINDOW);
        let lanes = std::array::from_fn(|k| run.contains(&(start + k)));
        Some(Self {
            start,
            lanes,
            keep: lanes.map(|lane| if lane { u64::MAX } else { 0 }),
        })
    }
}

/// The scalars an FMI 3.0 value reference names: `len` consecutive table entries from
/// `first`, of the type whose [`Access::type_bit`] is `type_bit`; value reference 0, `time`,
/// has `len` 0 (read and set apart).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Span {
    /// The table index of the first scalar.
    pub first: u32,
    /// The number of scalars (0 for `time`).
    pub len: u32,
    /// The scalars' type, as its bit.
    pub type_bit: u32,
}

impl Interface {
    /// The interface of `info`.
    pub fn new(info: ModelInfo) -> Self {
        let access: Vec<Access> = info.variables.iter().map(Access::of).collect();
        let layout = Layout::of(&info.variables);
        let computed = computed_runs(&info.variables);
        let computed_texts = computed
            .iter()
            .flat_map(|run| &info.variables[run.clone()])
            .any(|v| v.variable_type() == VariableType::String);
        let time = Span {
            first: 0,
            len: 0,
            type_bit: Access::type_bit(VariableType::Real),
        };
        let spans = std::iter::once(time)
            .chain(layout.variables().iter().map(|v| Span {
                first: v.first as u32,
                len: v.len() as u32,
                type_bit: Access::type_bit(access[v.first].variable_type),
            }))
            .collect();
        Self {
            window: Window::of(&computed, info.variables.len()),
            info,
            access,
            computed,
            computed_texts,
            layout,
            spans,
        }
    }

    /// The number of values the runs of [`Interface::computed`] hold.
    pub fn computed_len(&self) -> usize {
        self.computed.iter().map(|run| run.len()).sum()
    }
}

/// Interfaces built so far in this process, by model type and configuration. Bounded: a
/// process that instantiates more configurations than this rebuilds the oldest.
static INTERFACES: Mutex<Vec<(TypeId, Config, Arc<Interface>)>> = Mutex::new(Vec::new());
const INTERFACES_KEPT: usize = 64;

/// The interface of model `M` for `config`: built by [`FmuModel::describe`] on first use,
/// then shared by every instance of that configuration in the process (so an instance
/// carries no copy of its description, and instantiating needs no XML hashing).
pub fn interface<M: FmuModel>(config: &Config) -> Result<Arc<Interface>, Cause> {
    let key = TypeId::of::<M>();
    let find = |cache: &[(TypeId, Config, Arc<Interface>)]| {
        cache
            .iter()
            .find(|(t, c, _)| *t == key && c == config)
            .map(|(_, _, i)| Arc::clone(i))
    };
    if let Some(found) = find(&INTERFACES.lock().unwrap_or_else(|e| e.into_inner())) {
        return Ok(found);
    }
    // Described outside the lock: a model's `describe` may take a while.
    let built = Arc::new(Interface::new(M::describe(config)?));
    let mut cache = INTERFACES.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(found) = find(&cache) {
        return Ok(found);
    }
    if cache.len() >= INTERFACES_KEPT {
        cache.remove(0);
    }
    cache.push((key, config.clone(), Arc::clone(&built)));
    Ok(built)
}
