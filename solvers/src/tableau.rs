//! The coefficients of the methods, written once: the Dormand–Prince 5(4) pair with its
//! continuous extension, and four-stage Rosenbrock methods. The fixed-size integrators of the
//! math crate (`spurio::ode`) use these same constants, so both integrate with one table.

/// Dormand–Prince 5(4) (Dormand & Prince 1980, "A family of embedded Runge–Kutta formulae",
/// J. Comput. Appl. Math. 6; Hairer, Nørsett & Wanner, *Solving ODEs I*, §II.5, table 5.2):
/// nodes `cᵢ` of stages 2 … 7.
pub const DP5_C: [f64; 6] = [1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];

/// Dormand–Prince 5(4) stage weights: row `i` gives stage `i + 2` as
/// `x₀ + h Σⱼ aᵢⱼ kⱼ`; the last row is the fifth-order solution (first same as last: its
/// derivative is stage 7 and the next step's stage 1).
pub const DP5_A: [[f64; 6]; 6] = [
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [
        19372.0 / 6561.0,
        -25360.0 / 2187.0,
        64448.0 / 6561.0,
        -212.0 / 729.0,
        0.0,
        0.0,
    ],
    [
        9017.0 / 3168.0,
        -355.0 / 33.0,
        46732.0 / 5247.0,
        49.0 / 176.0,
        -5103.0 / 18656.0,
        0.0,
    ],
    [
        35.0 / 384.0,
        0.0,
        500.0 / 1113.0,
        125.0 / 192.0,
        -2187.0 / 6784.0,
        11.0 / 84.0,
    ],
];

/// Dormand–Prince 5(4) error weights `eᵢ = b₅ᵢ − b₄ᵢ` on stages 1 … 7: the local error
/// estimate is `h Σ eᵢ kᵢ`.
pub const DP5_E: [f64; 7] = [
    71.0 / 57600.0,
    0.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
];

/// The continuous extension of order 4 of Dormand–Prince 5(4) (Hairer, Nørsett & Wanner,
/// *Solving ODEs I*, §II.6, and their code DOPRI5, `CONTD5`): weights `dᵢ` on stages
/// 1, 3, 4, 5, 6, 7 of the fifth coefficient `r₅ = h Σ dᵢ kᵢ` of
///
/// ```text
/// x(t₀ + θh) = r₁ + θ (r₂ + (1−θ) (r₃ + θ (r₄ + (1−θ) r₅)))
/// r₁ = x₀,  r₂ = x₁ − x₀,  r₃ = h k₁ − r₂,  r₄ = r₂ − h k₇ − r₃
/// ```
pub const DP5_DENSE: [f64; 6] = [
    -12715105075.0 / 11282082432.0,
    87487479700.0 / 32700410799.0,
    -10690763975.0 / 1880347072.0,
    701980252875.0 / 199316789632.0,
    -1453857185.0 / 822651844.0,
    69997945.0 / 29380423.0,
];

/// A four-stage Rosenbrock method in the form `G kᵢ = f(t₀ + αᵢh, x₀ + Σⱼ aᵢⱼ kⱼ) +
/// Σⱼ cᵢⱼ kⱼ/h + γᵢ h ∂f/∂t`, `G = I/(γh) − J`, `x₁ = x₀ + Σ bᵢ kᵢ`, error estimate
/// `Σ eᵢ kᵢ` (Hairer & Wanner, *Solving ODEs II*, §IV.7, the transformed form (7.25)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RosenbrockMethod {
    /// `γ`.
    pub gamma: f64,
    /// `a₂₁, a₃₁, a₃₂, a₄₁, a₄₂, a₄₃`.
    pub a: [f64; 6],
    /// `c₂₁, c₃₁, c₃₂, c₄₁, c₄₂, c₄₃`.
    pub c: [f64; 6],
    /// `b₁ … b₄`.
    pub b: [f64; 4],
    /// `e₁ … e₄`.
    pub e: [f64; 4],
    /// Order of the embedded solution plus one (the exponent of the step control is −1/this).
    pub error_order: f64,
    /// The stages' times `αᵢ` (fractions of the step) for a non-autonomous `f`.
    pub alpha: [f64; 4],
    /// The stages' weights `γᵢ` on `h ∂f/∂t` for a non-autonomous `f`.
    pub gamma_t: [f64; 4],
}

/// RODAS3 (Sandu et al. 1997, "Benchmarking stiff ODE solvers for atmospheric chemistry
/// problems II: Rosenbrock solvers", Atmos. Environ. 31): order 3 with an embedded order-2
/// solution, L-stable, stiffly accurate; `γ = 1/2`.
pub const RODAS3: RosenbrockMethod = RosenbrockMethod {
    gamma: 0.5,
    a: [0.0, 2.0, 0.0, 2.0, 0.0, 1.0],
    c: [4.0, 1.0, -1.0, 1.0, -1.0, -8.0 / 3.0],
    b: [2.0, 0.0, 1.0, 1.0],
    e: [0.0, 0.0, 0.0, 1.0],
    error_order: 3.0,
    alpha: [0.0, 0.0, 1.0, 1.0],
    gamma_t: [0.5, 1.5, 0.0, 0.0],
};

/// Shampine's fourth-order Kaps–Rentrop parameters (Shampine 1982, "Implementation of
/// Rosenbrock methods", ACM TOMS 8; Hairer & Wanner §IV.7): order 4 with an embedded
/// order-3 solution, A-stable; stage 4 reuses stage 3's point.
pub const SHAMPINE4: RosenbrockMethod = RosenbrockMethod {
    gamma: 0.5,
    a: [2.0, 48.0 / 25.0, 6.0 / 25.0, 48.0 / 25.0, 6.0 / 25.0, 0.0],
    c: [
        -8.0,
        372.0 / 25.0,
        12.0 / 5.0,
        -112.0 / 125.0,
        -54.0 / 125.0,
        -2.0 / 5.0,
    ],
    b: [19.0 / 9.0, 0.5, 25.0 / 108.0, 125.0 / 108.0],
    e: [17.0 / 54.0, 7.0 / 36.0, 0.0, 125.0 / 108.0],
    error_order: 4.0,
    alpha: [0.0, 1.0, 3.0 / 5.0, 3.0 / 5.0],
    gamma_t: [0.5, -1.5, 121.0 / 50.0, 29.0 / 250.0],
};
