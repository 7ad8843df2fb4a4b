//! The coefficients of the methods, written once: the Dormand–Prince 5(4) pair with its
//! continuous extension, four-stage Rosenbrock methods, and RODAS4 with its dense output. The
//! fixed-size integrators of the math crate (`spurio::ode`) use these same constants, so both
//! integrate with one table.

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

/// The most stages of a [`RosenbrockTableau`].
pub const MAX_STAGES: usize = 6;

/// The entries of a strictly lower triangular `MAX_STAGES × MAX_STAGES` matrix, packed by rows.
const PACKED: usize = MAX_STAGES * (MAX_STAGES - 1) / 2;

/// A Rosenbrock method of up to [`MAX_STAGES`] stages in the transformed form of
/// [`RosenbrockMethod`] (`aᵢⱼ`, `cᵢⱼ` packed by rows: `a₂₁, a₃₁, a₃₂, a₄₁, …`), with, when it
/// has one, a continuous extension from its stages: for `θ ∈ [0, 1]`,
///
/// ```text
/// x(t₀ + θh) ≈ (1 − θ) x₀ + θ (x₁ + (1 − θ) (r₁ + θ r₂)),   r_m = Σᵢ dₘᵢ kᵢ
/// ```
///
/// (Hairer & Wanner, *Solving ODEs II*, §VI.4, the dense output of RODAS). It matches `x₀` and
/// `x₁` at the ends and is built from the stages, so on a stiff component it stays on the
/// slow manifold as the stages do, where a Hermite cubic through the end derivatives does not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RosenbrockTableau {
    /// The number of stages `s`.
    pub stages: usize,
    /// `γ`.
    pub gamma: f64,
    /// `aᵢⱼ`, packed (zero beyond the stages).
    pub a: [f64; PACKED],
    /// `cᵢⱼ`, packed.
    pub c: [f64; PACKED],
    /// `b₁ … b_s`.
    pub b: [f64; MAX_STAGES],
    /// `e₁ … e_s`: the local error estimate is `Σ eᵢ kᵢ`.
    pub e: [f64; MAX_STAGES],
    /// Order of the embedded solution plus one (the exponent of the step control is −1/this).
    pub error_order: f64,
    /// The stages' times `αᵢ`.
    pub alpha: [f64; MAX_STAGES],
    /// The stages' weights `γᵢ` on `h ∂f/∂t`.
    pub gamma_t: [f64; MAX_STAGES],
    /// `d₁ᵢ` and `d₂ᵢ` of the continuous extension, when the method has one.
    pub dense: Option<[[f64; MAX_STAGES]; 2]>,
}

impl From<RosenbrockMethod> for RosenbrockTableau {
    /// A four-stage method, without a continuous extension of its own.
    fn from(m: RosenbrockMethod) -> Self {
        let pad4 = |v: [f64; 4]| [v[0], v[1], v[2], v[3], 0.0, 0.0];
        let pad6 = |v: [f64; 6]| {
            let mut out = [0.0; PACKED];
            out[..6].copy_from_slice(&v);
            out
        };
        Self {
            stages: 4,
            gamma: m.gamma,
            a: pad6(m.a),
            c: pad6(m.c),
            b: pad4(m.b),
            e: pad4(m.e),
            error_order: m.error_order,
            alpha: pad4(m.alpha),
            gamma_t: pad4(m.gamma_t),
            dense: None,
        }
    }
}

/// RODAS4 (Hairer & Wanner, *Solving ODEs II*, §VI.4, Table 4.3 and their code RODAS,
/// `ROCOE` with `METH = 1`): six stages, order 4 with an embedded order-3 solution, L-stable
/// and stiffly accurate (the solution is the last stage's point plus `k₆`, the embedded one
/// the fifth's plus `k₅`: `b = (a₅₁, a₅₂, a₅₃, a₅₄, 1, 1)`, `e = k₆`), `γ = 1/4`, with a
/// continuous extension of order 3 (`d₁ᵢ`, `d₂ᵢ` on stages 1 … 5).
pub const RODAS4: RosenbrockTableau = {
    const A5: [f64; 4] = [
        1.221224509226641,
        6.019134481288629,
        12.53708332932087,
        -0.687886036105895,
    ];
    RosenbrockTableau {
        stages: 6,
        gamma: 0.25,
        a: [
            1.544,
            0.9466785280815826,
            0.2557011698983284,
            3.314825187068521,
            2.896124015972201,
            0.9986419139977817,
            A5[0],
            A5[1],
            A5[2],
            A5[3],
            A5[0],
            A5[1],
            A5[2],
            A5[3],
            1.0,
        ],
        c: [
            -5.6688,
            -2.430093356833875,
            -0.2063599157091915,
            -0.1073529058151375,
            -9.594562251023355,
            -20.47028614809616,
            7.496443313967647,
            -10.24680431464352,
            -33.99990352819905,
            11.7089089320616,
            8.083246795921522,
            -7.981132988064893,
            -31.52159432874371,
            16.31930543123136,
            -6.058818238834054,
        ],
        b: [A5[0], A5[1], A5[2], A5[3], 1.0, 1.0],
        e: [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        error_order: 4.0,
        alpha: [0.0, 0.386, 0.21, 0.63, 1.0, 1.0],
        gamma_t: [0.25, -0.1043, 0.1035, -0.03620000000000023, 0.0, 0.0],
        dense: Some([
            [
                10.12623508344586,
                -7.487995877610167,
                -34.80091861555747,
                -7.992771707568823,
                1.025137723295662,
                0.0,
            ],
            [
                -0.6762803392801253,
                6.087714651680015,
                16.43084320892478,
                24.76722511418386,
                -6.594389125716872,
                0.0,
            ],
        ]),
    }
};
