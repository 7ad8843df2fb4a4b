/* The misuse driver: drives one FMI 2.0 Co-Simulation FMU through its C ABI with a seeded
 * random sequence of calls -- legal and illegal call sequences, NULL pointers, unknown value
 * references, NaN/+-inf/1e308 values, huge, tiny, negative and non-finite steps, FMU states
 * that are foreign, corrupted or freed, several interleaved instances -- and checks after
 * every call:
 *
 *   - the state machine: a call that the FMI 2.0 state machine does not allow in any state
 *     the instance may be in returns fmi2Error (and changes nothing that is tracked);
 *   - every return other than fmi2OK/fmi2Warning on an instance logged why (at least one
 *     message with status >= fmi2Discard during the call), always with the format "%s";
 *   - no fmi2Fatal (a caught panic is a bug), no fmi2Pending;
 *   - no call takes longer than the bound (default 1 s);
 *   - every Real read with fmi2OK is finite; after every fmi2OK step all Reals are read.
 *
 * An FMU with Model Exchange is instantiated for it in a share of the instantiations, and its
 * Model Exchange instances are driven through the Model Exchange functions too (fmi2SetTime,
 * fmi2Set/GetContinuousStates, fmi2GetDerivatives, fmi2GetEventIndicators,
 * fmi2GetNominalsOfContinuousStates, fmi2EnterEventMode, fmi2NewDiscreteStates,
 * fmi2EnterContinuousTimeMode, fmi2CompletedIntegratorStep, fmi2GetDirectionalDerivative):
 * in the wrong mode, with NULL arrays, array sizes other than the model's, non-finite and
 * huge states and times, unknown value references -- and the same checks; every array read
 * with fmi2OK is finite, and after every fmi2OK fmi2SetContinuousStates the derivatives and
 * all Reals are read. A Co-Simulation instance of such an FMU gets a few of these calls too
 * (each must be refused).
 *
 * An FMI 3.0 FMU with Model Exchange (manifest version 3, from build/fmus/fmi3) is driven
 * through the FMI 3.0 Model Exchange state machine likewise (see "FMI 3.0 Model Exchange"
 * below), with the same checks; every FMI 3.0 FMU (manifest `interface cs`) through the FMI
 * 3.0 Co-Simulation state machine too (see "FMI 3.0 Co-Simulation").
 *
 * A crash, a hang or an AddressSanitizer report ends the process (the run script reports it).
 *
 *   driver MANIFEST SEED CALLS [BOUND_MS [FOREIGN_STATE_FILE [DUMP_FILE]]]
 *   MISUSE_TRACE=1 driver ...     # also prints every checked call, its status and message
 *
 * MANIFEST is written by manifest.py. The driver prints one summary line and each finding
 * with the call number, so `driver MANIFEST SEED N` replays it. Exit status: 0 no finding,
 * 1 findings, 2 usage or load error.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <time.h>
#include <unistd.h>

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
typedef int fmi2Status;
enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending };
enum { fmi2ModelExchange, fmi2CoSimulation };
enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated };

typedef void (*Logger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String,
                       ...);
typedef struct {
    Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

/* ---- the FMU's entry points ---------------------------------------------------------- */
static struct {
    fmi2Component (*Instantiate)(fmi2String, int, fmi2String, fmi2String,
                                 const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
    void (*FreeInstance)(fmi2Component);
    fmi2Status (*SetDebugLogging)(fmi2Component, fmi2Boolean, size_t, const fmi2String *);
    fmi2Status (*SetupExperiment)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean,
                                  fmi2Real);
    fmi2Status (*EnterInitializationMode)(fmi2Component);
    fmi2Status (*ExitInitializationMode)(fmi2Component);
    fmi2Status (*Terminate)(fmi2Component);
    fmi2Status (*Reset)(fmi2Component);
    fmi2Status (*GetReal)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Real *);
    fmi2Status (*GetInteger)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Integer *);
    fmi2Status (*GetBoolean)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Boolean *);
    fmi2Status (*GetString)(fmi2Component, const fmi2ValueReference *, size_t, fmi2String *);
    fmi2Status (*SetReal)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Real *);
    fmi2Status (*SetInteger)(fmi2Component, const fmi2ValueReference *, size_t,
                             const fmi2Integer *);
    fmi2Status (*SetBoolean)(fmi2Component, const fmi2ValueReference *, size_t,
                             const fmi2Boolean *);
    fmi2Status (*SetString)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2String *);
    fmi2Status (*GetFMUstate)(fmi2Component, fmi2FMUstate *);
    fmi2Status (*SetFMUstate)(fmi2Component, fmi2FMUstate);
    fmi2Status (*FreeFMUstate)(fmi2Component, fmi2FMUstate *);
    fmi2Status (*SerializedFMUstateSize)(fmi2Component, fmi2FMUstate, size_t *);
    fmi2Status (*SerializeFMUstate)(fmi2Component, fmi2FMUstate, fmi2Byte *, size_t);
    fmi2Status (*DeSerializeFMUstate)(fmi2Component, const fmi2Byte *, size_t, fmi2FMUstate *);
    fmi2Status (*DoStep)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
    fmi2Status (*CancelStep)(fmi2Component);
    fmi2Status (*GetStatus)(fmi2Component, int, fmi2Status *);
    fmi2Status (*GetRealStatus)(fmi2Component, int, fmi2Real *);
    fmi2Status (*GetIntegerStatus)(fmi2Component, int, fmi2Integer *);
    fmi2Status (*GetBooleanStatus)(fmi2Component, int, fmi2Boolean *);
    fmi2Status (*GetStringStatus)(fmi2Component, int, fmi2String *);
    /* Model Exchange (loaded when the FMU offers it; the functions FMI 3.0 shares: ME) */
    fmi2Status (*NewDiscreteStates)(fmi2Component, void *);
    fmi2Status (*GetDirectionalDerivative)(fmi2Component, const fmi2ValueReference *, size_t,
                                           const fmi2ValueReference *, size_t, const fmi2Real *,
                                           fmi2Real *);
} F;

/* fmi2EventInfo of fmi2FunctionTypes.h */
typedef struct {
    fmi2Boolean newDiscreteStatesNeeded, terminateSimulation, nominalsOfContinuousStatesChanged,
        valuesOfContinuousStatesChanged, nextEventTimeDefined;
    fmi2Real nextEventTime;
} fmi2EventInfo;

/* ---- the FMI 2.0 CS and ME state machines (as the standard's tables give them) --------- */
enum { S_INSTANTIATED = 1, S_INIT = 2, S_STEP = 4, S_TERMINATED = 8, S_ERROR = 16, S_FATAL = 32,
       S_EVENT = 64, S_CONT = 128 };
#define ME_MODES (S_EVENT | S_CONT)
#define ANY_LIVE (S_INSTANTIATED | S_INIT | S_STEP | S_TERMINATED | S_ERROR | ME_MODES)
#define AFTER_INIT (S_INIT | S_STEP | S_TERMINATED | S_ERROR | ME_MODES)
#define SETTABLE (S_INSTANTIATED | S_INIT | S_STEP | ME_MODES)
#define STATUS_QUERIES (S_STEP | S_TERMINATED)

/* ---- the model ----------------------------------------------------------------------- */
typedef struct {
    unsigned vr;
    char type; /* R I B S */
    char causality[24];
    char variability[16];
    int has_min, has_max;
    double min, max;
    char name[128];
} Var;

static char label[128], model_id[128], guid[128], library[1024], resources[1200];
static int version = 2;    /* the FMI version of the manifest's FMU */
static int model_exchange; /* the FMU offers Model Exchange too: fmi2ModelExchange is valid */
static int nz;             /* its event indicators */
static int nx;             /* its continuous states: state_vr[k], their derivatives der_vr[k] */
static fmi2ValueReference state_vr[64], der_vr[64];
static Var *vars;
static int nvars;
static unsigned max_vr;

/* ---- bookkeeping --------------------------------------------------------------------- */
typedef struct {
    fmi2Component c;
    int me;            /* instantiated for Model Exchange */
    int possible;      /* the states the instance may be in (bit set) */
    double time;       /* communication point when known */
    int time_known;
    int log_count;     /* messages with status >= fmi2Discard during the current call */
    int bad_format;    /* a message whose format was not "%s" */
    char last[600];
    fmi2FMUstate states[8];
    int state_possible[8];
    int nstates;
} Inst;

#define NINST 4
static Inst inst[NINST];
static unsigned long long rng;
static long call_no, findings, calls_total, calls_me; /* calls_me: on Model Exchange instances */
static double bound_ms = 1000.0, slowest_ms;
static char slowest_what[64];
static unsigned char *foreign;
static size_t foreign_len;
static unsigned char *own_bytes;
static size_t own_len;
static const char *dump_path;
static int trace; /* MISUSE_TRACE set: every checked call printed (to replay a finding) */

static unsigned long long next_u64(void) {
    /* splitmix64 */
    unsigned long long z = (rng += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}
static int pick(int n) { return (int)(next_u64() % (unsigned long long)n); }
static double unit(void) { return (double)(next_u64() >> 11) / 9007199254740992.0; }

static void finding(const char *what, const char *fmt, ...) {
    va_list ap;
    findings++;
    if (findings > 50) return;
    printf("FINDING %s call %ld (%s): ", label, call_no, what);
    va_start(ap, fmt);
    vprintf(fmt, ap);
    va_end(ap);
    printf("\n");
}

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    Inst *in = (Inst *)env;
    char text[600];
    va_list ap;
    (void)name;
    (void)category;
    if (!message) {
        if (in) in->bad_format = 1;
        return;
    }
    va_start(ap, message);
    vsnprintf(text, sizeof text, message, ap);
    va_end(ap);
    if (!in) return;
    if (strcmp(message, "%s") != 0) in->bad_format = 1;
    if (status >= fmi2Discard) {
        in->log_count++;
        snprintf(in->last, sizeof in->last, "%s", text);
    }
}

static fmi2CallbackFunctions callbacks_for(Inst *in) {
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, in};
    return cb;
}

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

/* Wraps a call on an instance: timing, the log and the state-machine checks.
 * `mask` is where the call is allowed; returns the status. */
static double t0;
static unsigned hang_seconds = 10;

/* A call that does not return: the alarm reports it (the process then ends). */
static void on_alarm(int sig) {
    char text[160];
    int n = snprintf(text, sizeof text, "HANG %s: call %ld did not return within %u s\n", label,
                     call_no, hang_seconds);
    (void)sig;
    if (n > 0) { ssize_t ignored = write(1, text, (size_t)n); (void)ignored; }
    _exit(3);
}

/* One fmi2Set* (set) or fmi2Get* of type t ('R', 'I', 'B'; 'S' to get) on n values, one call in
   25 with a NULL array instead (fmi2SetReal's values or fmi2SetInteger's references when
   setting, fmi2GetReal's values when getting). */
static fmi2Status values_call(Inst *in, int set, char t, const fmi2ValueReference *vrs, size_t n,
                              fmi2Real *xr, fmi2Integer *xi, fmi2String *xs) {
    if (pick(25) == 0) {
        if (!set) return F.GetReal(in->c, vrs, n, NULL);
        return t == 'R' ? F.SetReal(in->c, NULL, n, xr) : F.SetInteger(in->c, vrs, n, NULL);
    }
    switch (t) {
    case 'R': return set ? F.SetReal(in->c, vrs, n, xr) : F.GetReal(in->c, vrs, n, xr);
    case 'I': return set ? F.SetInteger(in->c, vrs, n, xi) : F.GetInteger(in->c, vrs, n, xi);
    case 'B': return set ? F.SetBoolean(in->c, vrs, n, xi) : F.GetBoolean(in->c, vrs, n, xi);
    default: return F.GetString(in->c, vrs, n, xs);
    }
}

static void begin(Inst *in) {
    alarm(hang_seconds);
    in->log_count = 0;
    in->last[0] = 0;
    t0 = now_ms();
    call_no++;
    calls_total++;
    calls_me += in->me;
}

static fmi2Status end(Inst *in, const char *what, int mask, fmi2Status s) {
    double ms = now_ms() - t0;
    alarm(0);
    if (ms > slowest_ms) {
        slowest_ms = ms;
        snprintf(slowest_what, sizeof slowest_what, "%s", what);
    }
    if (ms > bound_ms) finding(what, "took %.0f ms (bound %.0f ms)", ms, bound_ms);
    if (s == fmi2Fatal) {
        finding(what, "%s: %s", version == 3 ? "fmi3Fatal" : "fmi2Fatal", in->last);
        in->possible = S_FATAL;
    }
    if (s < fmi2OK || s > fmi2Fatal) finding(what, "status %d is not a status here", s);
    if (s >= fmi2Discard && in->log_count == 0) finding(what, "returned %d without logging why", s);
    if (in->bad_format) {
        finding(what, "logged with a format other than \"%%s\"");
        in->bad_format = 0;
    }
    if (trace)
        printf("call %ld %s on i%d: %d (%s)\n", call_no, what, (int)(in - inst), s, in->last);
    if (mask >= 0 && (mask & in->possible) == 0 && s != fmi2Error && s != fmi2Fatal)
        finding(what, "allowed in none of the states 0x%x but returned %d", in->possible, s);
    if (mask >= 0 && s == fmi2Error && strstr(in->last, "illegal call sequence")) {
        if ((in->possible & ~mask) == 0)
            finding(what, "refused as an illegal call sequence in an allowed state: %s", in->last);
        in->possible &= ~mask;
        if (!in->possible) in->possible = ANY_LIVE;
    } else if (mask >= 0 && s <= fmi2Warning) {
        in->possible &= mask;
        if (!in->possible) in->possible = mask;
    }
    return s;
}

/* ---- values -------------------------------------------------------------------------- */
static double nasty_real(const Var *v) {
    switch (pick(16)) {
    case 0: return NAN;
    case 1: return INFINITY;
    case 2: return -INFINITY;
    case 3: return 1e308;
    case 4: return -1e308;
    case 5: return 1e-300;
    case 6: return -1.0;
    case 7: return 0.0;
    case 8: return v && v->has_min ? v->min : 1.0;
    case 9: return v && v->has_max ? v->max : 2.0;
    case 10: return v && v->has_max ? v->max * (1 + 1e-12) + 1e-300 : 1e6;
    default: {
        double lo = v && v->has_min ? v->min : -10.0, hi = v && v->has_max ? v->max : 10.0;
        if (hi - lo > 100.0) { lo = fmax(lo, -10.0); hi = fmin(hi, 10.0); }
        if (hi < lo) hi = lo;
        return lo + (hi - lo) * unit();
    }
    }
}

static int nasty_int(const Var *v) {
    switch (pick(10)) {
    case 0: return 2147483647;
    case 1: return -2147483647 - 1;
    case 2: return -1;
    case 3: return 0;
    case 4: return v && v->has_min ? (int)v->min : 1;
    case 5: return v && v->has_max ? (int)v->max : 3;
    default: {
        int lo = v && v->has_min ? (int)v->min : 0, hi = v && v->has_max ? (int)v->max : 5;
        if (hi - lo > 50) hi = lo + 50;
        return lo + pick(hi - lo + 1);
    }
    }
}

/* A value reference of type `t` (sometimes of another type or unknown). */
static unsigned some_vr(char t, const Var **var) {
    int k, tries;
    *var = NULL;
    if (pick(20) == 0) return pick(2) ? max_vr + 1 + (unsigned)pick(5) : 0xFFFFFFFFu;
    for (tries = 0; tries < 50; tries++) {
        k = pick(nvars);
        if (vars[k].type == t || pick(30) == 0) {
            *var = &vars[k];
            return vars[k].vr;
        }
    }
    return 0;
}

/* ---- reading every Real (the finiteness check) ---------------------------------------- */
/* A Model Exchange instance whose model failed (not an illegal call) may be in Error state. */
static void me_failed(Inst *in, fmi2Status s) {
    if (in->me && s == fmi2Error && !strstr(in->last, "illegal call sequence"))
        in->possible |= S_ERROR;
}

static void check_all_reals(Inst *in, const char *after) {
    fmi2ValueReference *vr = malloc(sizeof *vr * (nvars + 1));
    fmi2Real *x = malloc(sizeof *x * (nvars + 1));
    int n = 0, i;
    fmi2Status s;
    for (i = 0; i < nvars; i++)
        if (vars[i].type == 'R') vr[n++] = vars[i].vr;
    begin(in);
    s = F.GetReal(in->c, vr, n, x);
    end(in, "fmi2GetReal(all)", AFTER_INIT, s);
    me_failed(in, s);
    if (s == fmi2OK)
        for (i = 0; i < n; i++)
            if (!isfinite(x[i])) {
                const char *name = "?";
                int k;
                for (k = 0; k < nvars; k++)
                    if (vars[k].vr == vr[i] && vars[k].type == 'R') name = vars[k].name;
                finding("fmi2GetReal", "after %s: `%s` = %g with fmi2OK", after, name, x[i]);
            }
    free(vr);
    free(x);
}

/* ---- instances ----------------------------------------------------------------------- */
static void free_states(Inst *in) { in->nstates = 0; /* freed with the instance */ }

/* A new instance (for Model Exchange when `me`): Instantiated at time 0, no FMU state. */
static void instantiated(Inst *in, int me) {
    in->possible = S_INSTANTIATED;
    in->me = me;
    in->time = 0;
    in->time_known = 1;
    in->nstates = 0;
}

static void instantiate(Inst *in) {
    char name[32];
    fmi2CallbackFunctions cb;
    const char *g = guid;
    const char *res = resources;
    int variant = pick(12);
    int me = variant == 3 || (model_exchange && variant > 4 && pick(6) == 0);
    snprintf(name, sizeof name, "i%d", (int)(in - inst));
    in->log_count = 0;
    cb = callbacks_for(in);
    if (variant == 0) g = "{00000000-0000-0000-0000-000000000000}";
    if (variant == 1) res = NULL;
    t0 = now_ms();
    call_no++;
    calls_total++;
    in->c = F.Instantiate(variant == 2 ? "" : name, me ? fmi2ModelExchange : fmi2CoSimulation,
                          g, res, variant == 4 ? NULL : &cb, 0, pick(2));
    if (!in->c) {
        if (variant > 4 && variant != 1)
            finding("fmi2Instantiate", "returned NULL for a valid call: %s", in->last);
        if (variant != 4 && in->log_count == 0 && variant != 1)
            finding("fmi2Instantiate", "returned NULL without logging why");
        return;
    }
    if (variant <= 4 && variant != 1 && !(variant == 3 && model_exchange))
        finding("fmi2Instantiate", "accepted an invalid call (case %d)", variant);
    instantiated(in, me);
}

static void free_instance(Inst *in) {
    call_no++;
    calls_total++;
    F.FreeInstance(in->c);
    in->c = NULL;
    free_states(in);
}

/* ---- Model Exchange (both versions) ---------------------------------------------------- */
/* An array size for a model with `n` elements: mostly right, else off by one, zero or huge
   (the arrays passed have room for n + 1; a huge size must be refused before any access). */
#define ME_HUGE ((size_t)1 << 40)
static size_t me_size(int n) {
    switch (pick(12)) {
    case 0: return pick(3) ? (size_t)n + 1 : ME_HUGE;
    case 1: return n > 0 ? (size_t)n - 1 : 1;
    case 2: return 0;
    default: return (size_t)n;
    }
}

/* Checks that the `n` values of `what` read with fmi2OK are finite. */
static void me_finite(const char *what, const fmi2Real *x, size_t n) {
    size_t i;
    for (i = 0; i < n; i++)
        if (!isfinite(x[i])) {
            finding(what, "element %zu = %g with fmi2OK", i, x[i]);
            return;
        }
}

static fmi2Status plain_call(Inst *in, fmi2Status (*call)(fmi2Component), const char *what,
                             int mask);

/* The Model Exchange functions FMI 2.0 and FMI 3.0 share in shape -- (instance), (instance,
   time), (instance, array, size) -- and their names, loaded for the manifest's version: the
   calls below drive both alike. `enter_init` brings an instance into Initialization Mode,
   `check_all_reals` reads every Real. */
static struct {
    fmi2Status (*SetTime)(fmi2Component, fmi2Real);
    fmi2Status (*SetContinuousStates)(fmi2Component, const fmi2Real *, size_t);
    fmi2Status (*GetArray[4])(fmi2Component, fmi2Real *, size_t); /* states, derivatives,
                                                                    indicators, nominals */
    fmi2Status (*EnterEventMode)(fmi2Component), (*EnterContinuousTimeMode)(fmi2Component),
        (*ExitInitializationMode)(fmi2Component);
    fmi2Status (*CompletedIntegratorStep)(fmi2Component, fmi2Boolean, fmi2Boolean *, fmi2Boolean *);
    const char *array_names[4], *set_time, *set_states, *enter_event, *enter_continuous, *exit_init,
        *completed;
    void (*enter_init)(Inst *);
    void (*check_all_reals)(Inst *, const char *);
} ME;

/* a Co-Simulation instance refuses every Model Exchange call: mask 0 */
#define ME_MASK(m) (in->me ? (m) : 0)

/* One array read of the Model Exchange interface; `expected` is the model's size. */
static fmi2Status me_get_array(Inst *in, int which, fmi2Real *x, size_t n, int expected) {
    static const int masks[] = {S_INIT | ME_MODES | S_TERMINATED | S_ERROR,
                                S_INIT | ME_MODES | S_TERMINATED | S_ERROR,
                                S_INIT | ME_MODES | S_TERMINATED | S_ERROR,
                                S_INSTANTIATED | S_INIT | ME_MODES | S_TERMINATED | S_ERROR};
    const char *what = ME.array_names[which];
    fmi2Status s;
    fmi2Real *out = n && pick(25) == 0 ? NULL : x;
    begin(in);
    s = ME.GetArray[which](in->c, out, n);
    end(in, what, ME_MASK(masks[which]), s);
    if (s <= fmi2Warning && n != (size_t)expected)
        finding(what, "accepted %zu elements where the model has %d", n, expected);
    if (s <= fmi2Warning && !out && n) finding(what, "accepted a NULL array of %zu elements", n);
    if (s == fmi2OK && out && n == (size_t)expected) me_finite(what, out, n);
    me_failed(in, s);
    return s;
}

/* Enter Initialization Mode, Event Mode or Continuous-Time Mode (`call`, allowed in `mask` on
   a Model Exchange instance; the last two nowhere on a Co-Simulation one): on success the
   instance is in `next`. */
static void me_enter(Inst *in, fmi2Status (*call)(fmi2Component), const char *what, int mask,
                     int next) {
    fmi2Status s = plain_call(in, call, what, ME_MASK(mask));
    if (s <= fmi2Warning) in->possible = next;
    me_failed(in, s);
}

/* The legal way on towards Continuous-Time Mode, for an instance known to be in one state (the
   random calls rarely get there): true when it made a call. A Co-Simulation instance goes to
   Step Mode instead (and no further). */
static int me_advance(Inst *in) {
    fmi2Status s;
    if (in->possible == S_INSTANTIATED) ME.enter_init(in);
    else if (in->possible == S_INIT) {
        s = plain_call(in, ME.ExitInitializationMode, ME.exit_init, S_INIT);
        if (s <= fmi2Warning) {
            in->possible = in->me ? S_EVENT : S_STEP;
            ME.check_all_reals(in, ME.exit_init);
        } else if (s == fmi2Error && !strstr(in->last, "illegal call sequence"))
            in->possible |= S_ERROR; /* the model refused its parameters */
    } else if (in->possible == S_EVENT && in->me)
        me_enter(in, ME.EnterContinuousTimeMode, ME.enter_continuous, S_EVENT, S_CONT);
    else
        return 0;
    return 1;
}

/* SetTime: forward, backward, non-finite or huge. */
static void me_set_time(Inst *in) {
    double t = in->time_known && pick(5) ? in->time + (pick(4) ? 0.01 * pick(20) : -0.5)
                                         : nasty_real(NULL);
    fmi2Status s;
    begin(in);
    s = ME.SetTime(in->c, t);
    end(in, ME.set_time, ME_MASK(ME_MODES), s);
    if (s <= fmi2Warning) {
        if (!isfinite(t)) finding(ME.set_time, "accepted t = %g", t);
        in->time = t;
        in->time_known = 1;
    }
}

/* SetContinuousStates: the current ones moved, or nasty values; after a success the
   derivatives (and now and then the event indicators) and every Real are read. */
static void me_set_states(Inst *in) {
    /* room for every array at its size + 1 (the wrong sizes of me_size) */
    fmi2Real x[130], y[130];
    int kind = pick(4), i;
    size_t n = me_size(nx);
    fmi2Status s;
    for (i = 0; i <= nx; i++) x[i] = 0.0;
    if (kind > 0 && nx) {
        begin(in);
        s = ME.GetArray[0](in->c, x, (size_t)nx);
        end(in, ME.array_names[0], ME_MASK(S_INIT | ME_MODES | S_TERMINATED | S_ERROR), s);
        if (s != fmi2OK)
            for (i = 0; i < nx; i++) x[i] = 0.0;
        me_failed(in, s);
    }
    for (i = 0; i <= nx; i++) {
        if (kind == 0 || pick(8) == 0) x[i] = nasty_real(NULL);
        else x[i] += 0.01 * (unit() - 0.5);
    }
    begin(in);
    s = ME.SetContinuousStates(in->c, n && pick(25) == 0 ? NULL : x, n);
    end(in, ME.set_states, ME_MASK(S_CONT), s);
    if (s <= fmi2Warning) {
        if (n != (size_t)nx) finding(ME.set_states, "accepted %zu states of %d", n, nx);
        for (i = 0; i < (int)n && n != ME_HUGE; i++)
            if (!isfinite(x[i])) finding(ME.set_states, "accepted state %d = %g", i, x[i]);
        if (nx) me_get_array(in, 1, y, (size_t)nx, nx);
        if (nz && pick(2)) me_get_array(in, 2, y, (size_t)nz, nz);
        ME.check_all_reals(in, ME.set_states);
    }
    me_failed(in, s);
}

/* One of the four array reads, at a size me_size draws. */
static void me_read_array(Inst *in) {
    fmi2Real x[130];
    int which = pick(4);
    int expected = which == 2 ? nz : nx;
    me_get_array(in, which, x, me_size(expected), expected);
}

/* The arguments of a directional derivative: 1-8 unknowns (mostly state derivatives), 1-8
   knowns (mostly states) and their seeds (now and then non-finite). */
static void directional_args(fmi2ValueReference *u, size_t *nu, fmi2ValueReference *k,
                             size_t *nk, fmi2Real *seed) {
    const Var *var;
    size_t i;
    *nu = 1 + (size_t)pick(nx ? (nx < 8 ? nx : 8) : 2);
    *nk = 1 + (size_t)pick(nx ? (nx < 8 ? nx : 8) : 2);
    for (i = 0; i < *nu; i++) u[i] = nx && pick(8) ? der_vr[pick(nx)] : some_vr('R', &var);
    for (i = 0; i < *nk; i++) {
        k[i] = nx && pick(8) ? state_vr[pick(nx)] : some_vr('R', &var);
        seed[i] = pick(10) ? 1.0 : nasty_real(NULL);
    }
}

/* CompletedIntegratorStep, with NULL flags now and then: the flags it writes are booleans. */
static void me_completed(Inst *in) {
    fmi2Boolean event = 7, terminate = 7;
    int null = pick(20);
    fmi2Status s;
    begin(in);
    s = ME.CompletedIntegratorStep(in->c, pick(2), null == 0 ? NULL : &event,
                                   null == 1 ? NULL : &terminate);
    end(in, ME.completed, ME_MASK(S_CONT), s);
    if (s <= fmi2Warning && null > 1 && ((event != 0 && event != 1) || (terminate != 0 && terminate != 1)))
        finding(ME.completed, "flags %d, %d", event, terminate);
    me_failed(in, s);
}

/* After fmi2NewDiscreteStates / fmi3UpdateDiscreteStates (`what`, status `s`): the next event
   time, when defined, is finite; every Real is read. */
static void me_updated(Inst *in, const char *what, fmi2Status s, int next_defined, double next) {
    end(in, what, ME_MASK(S_EVENT), s);
    if (s <= fmi2Warning && next_defined && !isfinite(next))
        finding(what, "next event time %g", next);
    if (s == fmi2OK) ME.check_all_reals(in, what);
    me_failed(in, s);
}

/* FMI 2.0: fmi2EnterInitializationMode. */
static void enter_init2(Inst *in) {
    me_enter(in, F.EnterInitializationMode, "fmi2EnterInitializationMode", S_INSTANTIATED, S_INIT);
}

/* One of the Model Exchange calls both versions share, by `op` (0 to 79): SetTime (0-9),
   SetContinuousStates (10-29), an array read (30-54), EnterEventMode (55-62),
   EnterContinuousTimeMode (63-69), CompletedIntegratorStep (70-79). */
static void me_shared_call(Inst *in, int op) {
    if (op < 10) me_set_time(in);
    else if (op < 30) me_set_states(in);
    else if (op < 55) me_read_array(in);
    else if (op < 63) me_enter(in, ME.EnterEventMode, ME.enter_event, ME_MODES, S_EVENT);
    else if (op < 70)
        me_enter(in, ME.EnterContinuousTimeMode, ME.enter_continuous, S_EVENT, S_CONT);
    else me_completed(in);
}

static void me_call(Inst *in) {
    int op;
    fmi2Status s;
    if (in->me && pick(3) == 0 && me_advance(in)) return;
    op = pick(100);
    if (op < 80) {
        me_shared_call(in, op);
        return;
    }
    if (op < 90) { /* fmi2NewDiscreteStates */
        fmi2EventInfo info;
        int null = pick(20) == 0;
        memset(&info, 0, sizeof info);
        begin(in);
        s = F.NewDiscreteStates(in->c, null ? NULL : &info);
        me_updated(in, "fmi2NewDiscreteStates", s, info.nextEventTimeDefined, info.nextEventTime);
        if (s <= fmi2Warning && null) finding("fmi2NewDiscreteStates", "accepted a NULL eventInfo");
        return;
    }
    { /* fmi2GetDirectionalDerivative: derivatives by states, or unknown references */
        fmi2ValueReference u[8], k[8];
        fmi2Real seed[8], out[8];
        size_t nu, nk;
        int null = pick(20);
        directional_args(u, &nu, k, &nk, seed);
        begin(in);
        s = F.GetDirectionalDerivative(in->c, null == 0 ? NULL : u, nu, k, nk,
                                       null == 1 ? NULL : seed, null == 2 ? NULL : out);
        end(in, "fmi2GetDirectionalDerivative",
            in->me ? S_INIT | ME_MODES | S_TERMINATED | S_ERROR : -1, s);
        if (s <= fmi2Warning && null < 3) finding("fmi2GetDirectionalDerivative", "accepted a NULL array");
        if (s == fmi2OK && null >= 3) me_finite("fmi2GetDirectionalDerivative", out, nu);
        /* a model that cannot linearize (e.g. not initialized yet) fails: Error state */
        if (s == fmi2Error && !strstr(in->last, "illegal call sequence")) in->possible |= S_ERROR;
    }
}

/* ---- one random call ----------------------------------------------------------------- */
/* GetFMUstate / GetFMUState (`call`, `what`: the same type in both versions) into a free slot
   or over a held state (NULL out-pointer now and then): the slot, or -1. */
static int take_state(Inst *in, fmi2Status (*call)(fmi2Component, fmi2FMUstate *),
                      const char *what) {
    fmi2FMUstate st = NULL;
    int slot = in->nstates < 8 ? in->nstates : pick(8);
    fmi2Status s;
    if (slot < in->nstates) st = in->states[slot];
    begin(in);
    s = call(in->c, pick(30) ? &st : NULL);
    end(in, what, ANY_LIVE, s);
    if (s != fmi2OK || !st) return -1;
    in->states[slot] = st;
    in->state_possible[slot] = in->possible;
    if (slot == in->nstates) in->nstates++;
    return slot;
}

/* Drops held state `slot` (freed by the FMU): the last one takes its place. */
static void forget_state(Inst *in, int slot) {
    in->nstates--;
    in->states[slot] = in->states[in->nstates];
    in->state_possible[slot] = in->state_possible[in->nstates];
}

/* Holds state `st` (from a deserialization; the instance's states are `possible` after
   setting it) in a free slot, or frees it through `free_call` (`what`) when none is free. */
static void keep_state(Inst *in, fmi2FMUstate st, int possible,
                       fmi2Status (*free_call)(fmi2Component, fmi2FMUstate *), const char *what) {
    if (in->nstates < 8) {
        in->states[in->nstates] = st;
        in->state_possible[in->nstates] = possible;
        in->nstates++;
    } else {
        begin(in);
        end(in, what, ANY_LIVE, free_call(in->c, &st));
    }
}

static void save_bytes(Inst *in, fmi2FMUstate st) {
    size_t size = 0;
    fmi2Status s;
    begin(in);
    s = F.SerializedFMUstateSize(in->c, st, &size);
    end(in, "fmi2SerializedFMUstateSize", ANY_LIVE, s);
    if (s != fmi2OK) return;
    if (size > (1u << 26)) {
        finding("fmi2SerializedFMUstateSize", "%zu bytes", size);
        return;
    }
    free(own_bytes);
    own_bytes = malloc(size ? size : 1);
    own_len = size;
    begin(in);
    s = F.SerializeFMUstate(in->c, st, (fmi2Byte *)own_bytes, pick(10) == 0 && size ? size - 1 : size);
    end(in, "fmi2SerializeFMUstate", ANY_LIVE, s);
    if (s != fmi2OK) own_len = 0;
}

/* One checked call of a function that takes the instance alone (fmi2EnterInitializationMode,
 * fmi2ExitInitializationMode, fmi2Terminate, fmi2Reset). */
static fmi2Status plain_call(Inst *in, fmi2Status (*call)(fmi2Component), const char *what,
                             int mask) {
    fmi2Status s;
    begin(in);
    s = call(in->c);
    end(in, what, mask, s);
    return s;
}

static void random_call(Inst *in) {
    fmi2Status s;
    int op = pick(100), n, i;
    fmi2ValueReference vrs[8];
    const Var *var[8];
    if (!in->c) {
        instantiate(in);
        return;
    }
    if (model_exchange && (in->me ? pick(2) == 0 : pick(50) == 0)) {
        me_call(in);
        return;
    }
    if (op < 3) { /* free and come back later */
        free_instance(in);
        return;
    }
    if (op < 6) {
        double start = pick(4) == 0 ? nasty_real(NULL) : (pick(3) == 0 ? 1e12 : 0.0);
        double stop = pick(3) == 0 ? nasty_real(NULL) : start + 10.0;
        int stop_defined = pick(2);
        begin(in);
        s = F.SetupExperiment(in->c, pick(2), 1e-6, start, stop_defined, stop);
        end(in, "fmi2SetupExperiment", S_INSTANTIATED, s);
        if (s == fmi2OK) { in->time = start; in->time_known = 1; }
        return;
    }
    if (op < 23) { /* the instance-only calls: 6-11, 12-17, 18-19 and 20-22 */
        static const char *const names[] = {"fmi2EnterInitializationMode",
                                            "fmi2ExitInitializationMode", "fmi2Terminate",
                                            "fmi2Reset"};
        static const int masks[] = {S_INSTANTIATED, S_INIT, S_STEP | ME_MODES, ANY_LIVE};
        static const int next[] = {S_INIT, S_STEP, S_TERMINATED, S_INSTANTIATED};
        fmi2Status (*const calls[])(fmi2Component) = {F.EnterInitializationMode,
                                                      F.ExitInitializationMode, F.Terminate,
                                                      F.Reset};
        int k = op < 12 ? 0 : op < 18 ? 1 : op < 20 ? 2 : 3;
        s = plain_call(in, calls[k], names[k], masks[k]);
        if (k == 1) { /* fmi2ExitInitializationMode: a warning also enters Step Mode */
            if (s <= fmi2Warning) {
                in->possible = in->me ? S_EVENT : S_STEP;
                check_all_reals(in, names[k]);
            } else if (s == fmi2Error && !strstr(in->last, "illegal call sequence"))
                in->possible |= S_ERROR;
        } else if (s == fmi2OK) {
            in->possible = next[k];
            if (k == 3) { in->time = 0; in->time_known = 1; }
        }
        return;
    }
    if (op < 45) { /* fmi2DoStep */
        static const double steps[] = {0.01, 0.05, 0.1, 0.001, 1.0, 10.0, 1e3, 1e308, 1e-300,
                                       0.0, -0.1, NAN, INFINITY, 1e-12, 0.02, 0.5};
        double h = steps[pick(4) == 0 ? pick(16) : pick(4)];
        double t;
        if (!in->time_known && pick(2)) {
            fmi2Real last = NAN;
            begin(in);
            s = F.GetRealStatus(in->c, fmi2LastSuccessfulTime, &last);
            end(in, "fmi2GetRealStatus", -1, s);
            if (s == fmi2OK) { in->time = last; in->time_known = 1; }
        }
        t = in->time_known && pick(10) ? in->time : nasty_real(NULL);
        begin(in);
        s = F.DoStep(in->c, t, h, 1);
        end(in, "fmi2DoStep", S_STEP, s);
        if (s <= fmi2Warning) {
            in->time = t + h;
            if (!isfinite(in->time)) finding("fmi2DoStep", "accepted a step to t = %g", in->time);
            check_all_reals(in, "fmi2DoStep");
        } else if (s == fmi2Error && !strstr(in->last, "illegal call sequence"))
            in->possible |= S_ERROR;
        return;
    }
    n = 1 + pick(4);
    if (op < 60) { /* fmi2SetReal / Integer / Boolean */
        int kind = pick(3);
        char t = kind == 0 ? 'R' : kind == 1 ? 'I' : 'B';
        fmi2Real xr[8];
        fmi2Integer xi[8];
        for (i = 0; i < n; i++) {
            vrs[i] = some_vr(t, &var[i]);
            xr[i] = nasty_real(var[i]);
            xi[i] = t == 'B' ? pick(3) - (pick(4) == 0) : nasty_int(var[i]);
        }
        begin(in);
        s = values_call(in, 1, t, vrs, n, xr, xi, NULL);
        end(in, "fmi2Set*", SETTABLE, s);
        if (s == fmi2Error && !strstr(in->last, "illegal call sequence") &&
            (in->possible & (S_STEP | ME_MODES)))
            in->possible |= S_ERROR; /* tunable parameters may fail in the model */
        return;
    }
    if (op < 75) { /* fmi2Get* */
        int kind = pick(4);
        char t = "RIBS"[kind];
        fmi2Real xr[8];
        fmi2Integer xi[8];
        fmi2String xs[8];
        for (i = 0; i < n; i++) vrs[i] = some_vr(t, &var[i]);
        begin(in);
        s = values_call(in, 0, t, vrs, n, xr, xi, xs);
        end(in, "fmi2Get*", AFTER_INIT, s);
        if (s == fmi2OK && t == 'R')
            for (i = 0; i < n; i++)
                if (!isfinite(xr[i])) finding("fmi2GetReal", "vr %u = %g with fmi2OK", vrs[i], xr[i]);
        if (s == fmi2OK && t == 'S')
            for (i = 0; i < n; i++)
                if (!xs[i] || strlen(xs[i]) > 1000000) finding("fmi2GetString", "bad string");
        if (s == fmi2Error && !strstr(in->last, "illegal call sequence") &&
            (in->possible & (S_INIT | ME_MODES)))
            in->possible |= S_ERROR; /* outputs computed in initialization mode may fail */
        return;
    }
    if (op < 80) { /* fmi2GetFMUstate */
        int slot = take_state(in, F.GetFMUstate, "fmi2GetFMUstate");
        if (slot >= 0 && pick(3) == 0) save_bytes(in, in->states[slot]);
        return;
    }
    if (op < 85) { /* fmi2SetFMUstate: own, another instance's, or garbage */
        fmi2FMUstate st;
        int slot = in->nstates ? pick(in->nstates) : -1;
        int which = pick(6), not_ours = 0;
        Inst *other = &inst[pick(NINST)];
        if (which == 0 && other != in && other->c && other->nstates) {
            st = other->states[0];
            not_ours = 1;
        } else if (which == 1) {
            st = (fmi2FMUstate)(uintptr_t)0x1000;
            not_ours = 1;
        } else
            st = slot >= 0 ? in->states[slot] : NULL;
        begin(in);
        s = F.SetFMUstate(in->c, st);
        end(in, "fmi2SetFMUstate", ANY_LIVE, s);
        if (s == fmi2OK) {
            int k;
            in->possible = ANY_LIVE;
            for (k = 0; k < in->nstates; k++)
                if (in->states[k] == st) in->possible = in->state_possible[k];
            in->time_known = 0;
            if (not_ours) finding("fmi2SetFMUstate", "accepted a state it did not create");
        }
        return;
    }
    if (op < 88) { /* fmi2FreeFMUstate */
        if (in->nstates) {
            int slot = pick(in->nstates);
            fmi2FMUstate st = in->states[slot];
            begin(in);
            s = F.FreeFMUstate(in->c, &st);
            end(in, "fmi2FreeFMUstate", ANY_LIVE | S_FATAL, s);
            if (s == fmi2OK) {
                forget_state(in, slot);
                if (st) finding("fmi2FreeFMUstate", "did not set the state to NULL");
            }
        }
        return;
    }
    if (op < 94) { /* fmi2DeSerializeFMUstate: own bytes, corrupted, truncated, foreign */
        unsigned char *bytes;
        size_t len;
        fmi2FMUstate st = NULL;
        int which = pick(5), other_fmu = 0;
        if (which == 0) { /* another FMU's state (none: a fixed non-state), no random draw */
            static const char not_a_state[] = "not a serialized FMU state";
            other_fmu = foreign_len > 0;
            len = other_fmu ? foreign_len : sizeof not_a_state;
            bytes = malloc(len);
            memcpy(bytes, other_fmu ? (const void *)foreign : (const void *)not_a_state, len);
        } else if (own_len) {
            len = own_len;
            bytes = malloc(len);
            memcpy(bytes, own_bytes, len);
            if (which == 1) bytes[pick((int)len)] ^= (unsigned char)(1 + pick(255));
            if (which == 2) len = (size_t)pick((int)len);
            if (which == 3) { /* a NaN or an extreme number somewhere after the header */
                size_t at = (size_t)pick((int)len);
                double bad = pick(2) ? NAN : -1e308;
                if (at + 8 <= len) memcpy(bytes + at, &bad, 8);
            }
        } else {
            len = 1 + pick(64);
            bytes = malloc(len);
            for (size_t k = 0; k < len; k++) bytes[k] = (unsigned char)pick(256);
        }
        begin(in);
        s = F.DeSerializeFMUstate(in->c, (const fmi2Byte *)bytes, len, &st);
        end(in, "fmi2DeSerializeFMUstate", ANY_LIVE, s);
        if (s == fmi2OK && other_fmu) finding("fmi2DeSerializeFMUstate", "accepted the state of another FMU");
        if (s == fmi2OK) keep_state(in, st, ANY_LIVE, F.FreeFMUstate, "fmi2FreeFMUstate");
        free(bytes);
        return;
    }
    if (op < 97) { /* status queries */
        fmi2Real r;
        fmi2Boolean b;
        fmi2Status st;
        int kind = pick(5);
        begin(in);
        if (kind == 0) s = F.GetRealStatus(in->c, fmi2LastSuccessfulTime, pick(20) ? &r : NULL);
        else if (kind == 1) s = F.GetBooleanStatus(in->c, fmi2Terminated, &b);
        else if (kind == 2) s = F.GetStatus(in->c, fmi2DoStepStatus, &st);
        else if (kind == 3) s = F.CancelStep(in->c);
        else s = F.GetRealStatus(in->c, pick(7) - 1, &r);
        end(in, "status query", kind == 3 ? 0 : -1, s);
        if (kind == 0 && s == fmi2OK && !isfinite(r)) finding("fmi2GetRealStatus", "time %g", r);
        return;
    }
    { /* fmi2SetDebugLogging, fmi2SetString, NULL component */
        int kind = pick(3);
        if (kind == 0) {
            fmi2String cats[2] = {"logStatusError", pick(2) ? "noSuchCategory" : "logAll"};
            begin(in);
            s = F.SetDebugLogging(in->c, pick(2), 1 + pick(2), pick(20) ? cats : NULL);
            end(in, "fmi2SetDebugLogging", ANY_LIVE, s);
        } else if (kind == 1) {
            fmi2String v[1] = {pick(5) ? "text" : NULL};
            fmi2ValueReference r = some_vr('S', &var[0]);
            begin(in);
            s = F.SetString(in->c, &r, 1, v);
            end(in, "fmi2SetString", SETTABLE, s);
        } else {
            double ms = now_ms();
            calls_total++;
            call_no++;
            if (F.DoStep(NULL, 0, 0.1, 1) != fmi2Error || F.GetReal(NULL, NULL, 0, NULL) != fmi2Error ||
                F.EnterInitializationMode(NULL) != fmi2Error)
                finding("NULL component", "not fmi2Error");
            F.FreeInstance(NULL);
            if (now_ms() - ms > bound_ms) finding("NULL component", "slow");
        }
    }
}

/* ---- FMI 3.0 Model Exchange ---------------------------------------------------------- */
/* An FMI 3.0 FMU (manifest version 3) with Model Exchange: instantiated mostly for Model
 * Exchange (fmi3InstantiateModelExchange), now and then for Co-Simulation (whose instances must
 * refuse every Model Exchange call), and driven through the FMI 3.0 Model Exchange state
 * machine -- Instantiated -> Initialization Mode -> Event Mode <-> Continuous-Time Mode ->
 * Terminated -- with the same checks, in and out of the modes: fmi3SetTime,
 * fmi3Set/GetContinuousStates, fmi3GetContinuousStateDerivatives, fmi3GetEventIndicators,
 * fmi3GetNominalsOfContinuousStates, fmi3GetNumberOf{EventIndicators,ContinuousStates},
 * fmi3EnterEventMode, fmi3UpdateDiscreteStates, fmi3EnterContinuousTimeMode,
 * fmi3CompletedIntegratorStep, fmi3GetDirectionalDerivative, fmi3Get/SetFloat64, Int32,
 * Boolean (wrong nValues too), FMU states (own, freed, serialized, corrupted), fmi3Terminate,
 * fmi3Reset. */
typedef void *fmi3Instance;
typedef void *fmi3FMUState;
typedef unsigned int fmi3ValueReference;
typedef double fmi3Float64;
typedef int fmi3Int32;
typedef _Bool fmi3Boolean;
typedef int fmi3Status; /* fmi3OK .. fmi3Fatal: the same numbers as fmi2OK .. fmi2Fatal */
typedef void (*fmi3LogMessageCallback)(void *, fmi3Status, const char *, const char *);

static int counts[4096]; /* FMI 3.0: elements of the variable with each value reference (0: 1) */
static int count_of(unsigned vr) { return vr < 4096 && counts[vr] ? counts[vr] : 1; }

static struct {
    fmi3Instance (*InstantiateModelExchange)(const char *, const char *, const char *, fmi3Boolean,
                                             fmi3Boolean, void *, fmi3LogMessageCallback);
    fmi3Instance (*InstantiateCoSimulation)(const char *, const char *, const char *, fmi3Boolean,
                                            fmi3Boolean, fmi3Boolean, fmi3Boolean,
                                            const fmi3ValueReference *, size_t, void *,
                                            fmi3LogMessageCallback, void *);
    /* (fmi3FreeInstance: F.FreeInstance, of the same type as fmi2FreeInstance) */
    fmi3Status (*EnterInitializationMode)(fmi3Instance, fmi3Boolean, fmi3Float64, fmi3Float64,
                                          fmi3Boolean, fmi3Float64);
    fmi3Status (*ExitInitializationMode)(fmi3Instance);
    fmi3Status (*Terminate)(fmi3Instance);
    fmi3Status (*Reset)(fmi3Instance);
    fmi3Status (*GetFloat64)(fmi3Instance, const fmi3ValueReference *, size_t, fmi3Float64 *, size_t);
    fmi3Status (*GetInt32)(fmi3Instance, const fmi3ValueReference *, size_t, fmi3Int32 *, size_t);
    fmi3Status (*GetBoolean)(fmi3Instance, const fmi3ValueReference *, size_t, fmi3Boolean *, size_t);
    fmi3Status (*SetFloat64)(fmi3Instance, const fmi3ValueReference *, size_t, const fmi3Float64 *,
                             size_t);
    fmi3Status (*SetInt32)(fmi3Instance, const fmi3ValueReference *, size_t, const fmi3Int32 *, size_t);
    fmi3Status (*SetBoolean)(fmi3Instance, const fmi3ValueReference *, size_t, const fmi3Boolean *,
                             size_t);
    fmi3Status (*GetFMUState)(fmi3Instance, fmi3FMUState *);
    fmi3Status (*SetFMUState)(fmi3Instance, fmi3FMUState);
    fmi3Status (*FreeFMUState)(fmi3Instance, fmi3FMUState *);
    fmi3Status (*SerializedFMUStateSize)(fmi3Instance, fmi3FMUState, size_t *);
    fmi3Status (*SerializeFMUState)(fmi3Instance, fmi3FMUState, unsigned char *, size_t);
    fmi3Status (*DeserializeFMUState)(fmi3Instance, const unsigned char *, size_t, fmi3FMUState *);
    /* (the Model Exchange functions FMI 2.0 shares: ME) */
    fmi3Status (*GetNumber[2])(fmi3Instance, size_t *); /* event indicators, states */
    fmi3Status (*UpdateDiscreteStates)(fmi3Instance, fmi3Boolean *, fmi3Boolean *, fmi3Boolean *,
                                       fmi3Boolean *, fmi3Boolean *, fmi3Float64 *);
    fmi3Status (*CompletedIntegratorStep)(fmi3Instance, fmi3Boolean, fmi3Boolean *, fmi3Boolean *);
    fmi3Status (*GetDirectionalDerivative)(fmi3Instance, const fmi3ValueReference *, size_t,
                                           const fmi3ValueReference *, size_t, const fmi3Float64 *,
                                           size_t, fmi3Float64 *, size_t);
    fmi3Status (*GetAdjointDerivative)(fmi3Instance, const fmi3ValueReference *, size_t,
                                       const fmi3ValueReference *, size_t, const fmi3Float64 *,
                                       size_t, fmi3Float64 *, size_t);
    fmi3Status (*EvaluateDiscreteStates)(fmi3Instance); /* providesEvaluateDiscreteStates="false" */
    /* Co-Simulation (an `interface cs` manifest) */
    fmi3Status (*DoStep)(fmi3Instance, fmi3Float64, fmi3Float64, fmi3Boolean, fmi3Boolean *,
                         fmi3Boolean *, fmi3Boolean *, fmi3Float64 *);
    fmi3Status (*EnterStepMode)(fmi3Instance);
    fmi3Status (*GetString)(fmi3Instance, const fmi3ValueReference *, size_t, const char **, size_t);
    fmi3Status (*SetString)(fmi3Instance, const fmi3ValueReference *, size_t, const char *const *,
                            size_t);
    fmi3Status (*SetDebugLogging)(fmi3Instance, fmi3Boolean, size_t, const char *const *);
    /* types the FMUs declare no variable of (each call refused) */
    fmi3Status (*GetFloat32)(fmi3Instance, const fmi3ValueReference *, size_t, float *, size_t);
    fmi3Status (*SetInt8)(fmi3Instance, const fmi3ValueReference *, size_t, const int8_t *, size_t);
    fmi3Status (*GetUInt64)(fmi3Instance, const fmi3ValueReference *, size_t, uint64_t *, size_t);
    fmi3Status (*SetInt64)(fmi3Instance, const fmi3ValueReference *, size_t, const int64_t *, size_t);
    fmi3Status (*GetBinary)(fmi3Instance, const fmi3ValueReference *, size_t, size_t *,
                            const unsigned char **, size_t);
    fmi3Status (*GetClock)(fmi3Instance, const fmi3ValueReference *, size_t, fmi3Boolean *);
    fmi3Status (*GetOutputDerivatives)(fmi3Instance, const fmi3ValueReference *, size_t,
                                       const fmi3Int32 *, fmi3Float64 *, size_t);
} G;

/* FMI 3.0 Co-Simulation (manifest `interface cs`): the FMU's Co-Simulation capabilities. */
static int cs_interface, cs_event_mode, cs_intermediate;

/* The FMI 3.0 state machine's masks for a Model Exchange instance (FMI 3.0.2 section 3.3);
   S_STEP is never reached. */
#define ME3_GETTABLE (S_INIT | ME_MODES | S_TERMINATED | S_ERROR)
#define ME3_SETTABLE (S_INSTANTIATED | S_INIT | ME_MODES)

/* fmi3LogMessageCallback: the message is plain text (no format). */
static void logger3(void *env, fmi3Status status, const char *category, const char *message) {
    Inst *in = (Inst *)env;
    (void)category;
    if (!in) return;
    if (!message) {
        in->bad_format = 1;
        return;
    }
    if (status >= fmi2Discard) {
        in->log_count++;
        snprintf(in->last, sizeof in->last, "%s", message);
    }
}

static void instantiate3(Inst *in) {
    char name[32];
    const char *token = guid;
    int variant = pick(12);
    int cs = variant == 3 || (variant > 4 && pick(6) == 0);
    snprintf(name, sizeof name, "i%d", (int)(in - inst));
    in->log_count = 0;
    if (variant == 0) token = "{00000000-0000-0000-0000-000000000000}";
    t0 = now_ms();
    call_no++;
    calls_total++;
    const char *n = variant == 2 ? "" : variant == 4 ? NULL : name;
    const char *res = variant == 1 ? NULL : resources;
    in->c = cs ? G.InstantiateCoSimulation(n, token, res, 0, pick(2), 0, 0, NULL, 0, in, logger3, NULL)
               : G.InstantiateModelExchange(n, token, res, 0, pick(2), in, logger3);
    const char *what = cs ? "fmi3InstantiateCoSimulation" : "fmi3InstantiateModelExchange";
    if (!in->c) {
        if (variant > 4 || variant == 3) finding(what, "returned NULL for a valid call: %s", in->last);
        if (variant != 1 && in->log_count == 0) finding(what, "returned NULL without logging why");
        return;
    }
    if (variant == 0 || variant == 2 || variant == 4)
        finding(what, "accepted an invalid call (case %d)", variant);
    instantiated(in, !cs);
}

/* Every Float64 read at once (arrays whole); each must be finite when fmi3OK. */
static void check_all_reals3(Inst *in, const char *after) {
    fmi3ValueReference *vr = malloc(sizeof *vr * (nvars + 1));
    int n = 0, nvalues = 0, i;
    fmi3Float64 *x;
    fmi3Status s;
    for (i = 0; i < nvars; i++)
        if (vars[i].type == 'R') {
            vr[n++] = vars[i].vr;
            nvalues += count_of(vars[i].vr);
        }
    x = malloc(sizeof *x * (nvalues + 1));
    begin(in);
    s = G.GetFloat64(in->c, vr, n, x, nvalues);
    end(in, "fmi3GetFloat64(all)", ME3_GETTABLE | S_STEP, s);
    me_failed(in, s);
    if (s == fmi2OK)
        for (i = 0; i < nvalues; i++)
            if (!isfinite(x[i])) {
                finding("fmi3GetFloat64", "after %s: element %d = %g with fmi3OK", after, i, x[i]);
                break;
            }
    free(vr);
    free(x);
}

/* fmi3EnterInitializationMode with a start time (sometimes nasty) and a stop time. */
static void enter_init3(Inst *in) {
    double start = pick(6) == 0 ? nasty_real(NULL) : 0.0;
    double stop = pick(4) == 0 ? nasty_real(NULL) : start + 10.0;
    fmi3Status s;
    begin(in);
    s = G.EnterInitializationMode(in->c, pick(2), pick(8) ? 1e-6 : nasty_real(NULL), start, pick(2), stop);
    end(in, "fmi3EnterInitializationMode", S_INSTANTIATED, s);
    if (s <= fmi2Warning) {
        if (!isfinite(start)) finding("fmi3EnterInitializationMode", "accepted startTime = %g", start);
        in->possible = S_INIT;
        in->time = start;
        in->time_known = 1;
    }
}

/* fmi3Set/Get Float64, Int32 or Boolean on 1-4 value references, nValues mostly right. */
static void values3(Inst *in, int set) {
    fmi3ValueReference vrs[4];
    fmi3Float64 xr[64];
    fmi3Int32 xi[64];
    fmi3Boolean xb[64];
    const Var *var[4];
    int kind = pick(3), n = 1 + pick(4), nvalues = 0, i, k;
    char t = "RIB"[kind];
    size_t nv;
    fmi3Float64 *real = pick(25) ? xr : NULL; /* a NULL Float64 array now and then */
    fmi3Status s;
    for (i = 0; i < 64; i++) {
        xr[i] = nasty_real(NULL);
        xi[i] = nasty_int(NULL);
        xb[i] = pick(2);
    }
    for (i = 0; i < n; i++) { /* each value nasty for its variable (its bounds) */
        vrs[i] = some_vr(t, &var[i]);
        for (k = 0; k < count_of(vrs[i]) && nvalues + k < 60; k++) {
            xr[nvalues + k] = nasty_real(var[i]);
            xi[nvalues + k] = nasty_int(var[i]);
        }
        nvalues += count_of(vrs[i]);
    }
    if (nvalues > 60) nvalues = 60;
    nv = pick(12) == 0 ? (size_t)nvalues + 1 - (size_t)pick(3) : (size_t)nvalues;
    begin(in);
    if (set)
        s = t == 'R' ? G.SetFloat64(in->c, vrs, n, real, nv)
          : t == 'I' ? G.SetInt32(in->c, vrs, n, xi, nv)
                     : G.SetBoolean(in->c, vrs, n, xb, nv);
    else
        s = t == 'R' ? G.GetFloat64(in->c, vrs, n, real, nv)
          : t == 'I' ? G.GetInt32(in->c, vrs, n, xi, nv)
                     : G.GetBoolean(in->c, vrs, n, xb, nv);
    end(in, set ? "fmi3Set*" : "fmi3Get*", set ? ME3_SETTABLE | S_STEP : ME3_GETTABLE | S_STEP, s);
    if (s <= fmi2Warning && nv != (size_t)nvalues)
        finding(set ? "fmi3Set*" : "fmi3Get*", "accepted nValues = %zu for %d values", nv, nvalues);
    if (s <= fmi2Warning && t == 'R' && !real && nv)
        finding(set ? "fmi3SetFloat64" : "fmi3GetFloat64", "accepted a NULL array of %zu values", nv);
    if (!set && s == fmi2OK && t == 'R' && real)
        for (i = 0; i < (int)nv; i++)
            if (!isfinite(xr[i])) finding("fmi3GetFloat64", "element %d = %g with fmi3OK", i, xr[i]);
    if (s == fmi2Error && !strstr(in->last, "illegal call sequence") &&
        (in->possible & (S_INIT | ME_MODES | S_STEP)))
        in->possible |= S_ERROR; /* values computed or parameters applied may fail in the model */
}

/* fmi3GetFMUState, fmi3SetFMUState (own, garbage), fmi3FreeFMUState, serialize/deserialize. */
static void states3(Inst *in) {
    fmi3Status s;
    int op = pick(5);
    if (op == 0 || in->nstates == 0) {
        take_state(in, G.GetFMUState, "fmi3GetFMUState");
        return;
    }
    int slot = pick(in->nstates);
    fmi3FMUState st = in->states[slot];
    if (op == 1) { /* set: own or garbage */
        int garbage = pick(8) == 0;
        begin(in);
        s = G.SetFMUState(in->c, garbage ? (fmi3FMUState)(uintptr_t)0x1000 : st);
        end(in, "fmi3SetFMUState", ANY_LIVE, s);
        if (s == fmi2OK) {
            if (garbage) finding("fmi3SetFMUState", "accepted a state it did not create");
            in->possible = in->state_possible[slot];
            in->time_known = 0;
        }
    } else if (op == 2) { /* free */
        begin(in);
        s = G.FreeFMUState(in->c, &st);
        end(in, "fmi3FreeFMUState", ANY_LIVE, s);
        if (s == fmi2OK) {
            if (st) finding("fmi3FreeFMUState", "did not set the state to NULL");
            forget_state(in, slot);
        }
    } else { /* serialize, then deserialize the bytes (corrupted now and then) */
        size_t size = 0;
        unsigned char *bytes;
        fmi3FMUState back = NULL;
        begin(in);
        s = G.SerializedFMUStateSize(in->c, st, &size);
        end(in, "fmi3SerializedFMUStateSize", ANY_LIVE, s);
        if (s != fmi2OK || size > (1u << 26)) return;
        bytes = malloc(size ? size : 1);
        begin(in);
        s = G.SerializeFMUState(in->c, st, bytes, size);
        end(in, "fmi3SerializeFMUState", ANY_LIVE, s);
        if (s == fmi2OK) {
            int corrupt = pick(3) == 0 && size;
            if (corrupt) bytes[pick((int)size)] ^= (unsigned char)(1 + pick(255));
            begin(in);
            s = G.DeserializeFMUState(in->c, bytes, pick(6) == 0 && size ? size - 1 : size, &back);
            end(in, "fmi3DeserializeFMUState", ANY_LIVE, s);
            if (s == fmi2OK && back)
                keep_state(in, back, corrupt ? ANY_LIVE : in->state_possible[slot], G.FreeFMUState,
                           "fmi3FreeFMUState");
        }
        free(bytes);
    }
}

/* fmi3Terminate or fmi3Reset (`reset`): on success the instance is Terminated or
   Instantiated; a model failure may leave it in Error state. */
static void end_or_reset3(Inst *in, int reset) {
    fmi3Status s = reset ? plain_call(in, G.Reset, "fmi3Reset", ANY_LIVE)
                         : plain_call(in, G.Terminate, "fmi3Terminate", in->me ? ME_MODES : S_STEP);
    if (s <= fmi2Warning) {
        in->possible = reset ? S_INSTANTIATED : S_TERMINATED;
        in->time = 0;
        in->time_known = reset;
    } else if (s == fmi2Error && !strstr(in->last, "illegal call sequence"))
        in->possible |= S_ERROR;
}

/* ---- FMI 3.0 Co-Simulation ---------------------------------------------------------- */
/* An FMI 3.0 FMU driven as Co-Simulation (manifest `interface cs`, listed as fmi3-cs/<Model>):
 * every instance from fmi3InstantiateCoSimulation -- with eventModeUsed, earlyReturnAllowed and
 * requiredIntermediateVariables asked now and then (accepted only when the FMU declares
 * hasEventMode / providesIntermediateUpdate; earlyReturnAllowed always: it only permits) -- and
 * driven through the FMI 3.0 Co-Simulation state machine (Instantiated -> Initialization Mode
 * -> Step Mode -> Terminated; no Event Mode: hasEventMode="false") with the checks above:
 * fmi3DoStep at good and bad times and steps (NaN, +-inf, negative, 0, tiny, huge), its output
 * flags (no event handling, no early return from an FMU that declares neither) and
 * lastSuccessfulTime; fmi3EnterStepMode, fmi3EnterEventMode, fmi3UpdateDiscreteStates,
 * fmi3EvaluateDiscreteStates (refused: no Event Mode); fmi3Get/SetString and the getters and
 * setters of the types the FMUs do not declare (refused); FMU states (another instance's,
 * garbage, a non-state's bytes); NULL instances; and, through random_call3, the calls the two
 * interfaces share and every Model Exchange call (each refused on a Co-Simulation
 * instance). */

/* fmi3InstantiateCoSimulation, valid or not (`variant`); on a CS-only FMU, now and then
   fmi3InstantiateModelExchange, which must be refused. */
static void instantiate3cs(Inst *in) {
    static const fmi3ValueReference required[2] = {0, 1};
    char name[32];
    const char *token = guid, *what = "fmi3InstantiateCoSimulation";
    int variant = pick(16), valid;
    fmi3Boolean event_mode = variant == 5 || variant == 8, early = variant == 7 || variant == 8;
    snprintf(name, sizeof name, "i%d", (int)(in - inst));
    in->log_count = 0;
    in->last[0] = 0;
    if (variant == 0) token = "{00000000-0000-0000-0000-000000000000}";
    valid = variant >= 7 || (variant == 3 && model_exchange);
    if (variant == 5 || variant == 8) valid = cs_event_mode;
    if (variant == 6) valid = cs_intermediate;
    if (variant == 1) valid = -1; /* no resources: valid, but a variant FMU needs its own */
    t0 = now_ms();
    call_no++;
    calls_total++;
    if (variant == 3 && !model_exchange) {
        what = "fmi3InstantiateModelExchange";
        in->c = G.InstantiateModelExchange(name, token, resources, 0, pick(2), in, logger3);
    } else
        in->c = G.InstantiateCoSimulation(variant == 2 ? "" : variant == 4 ? NULL : name, token,
                                          variant == 1 ? NULL : resources, 0, pick(2), event_mode,
                                          early, variant == 6 ? required : NULL,
                                          variant == 6 ? 2 : 0, in, logger3, NULL);
    if (trace) printf("call %ld %s (case %d) on i%d: %s (%s)\n", call_no, what, variant,
                      (int)(in - inst), in->c ? "instance" : "NULL", in->last);
    if (!in->c) {
        if (valid == 1) finding(what, "returned NULL for a valid call (case %d): %s", variant, in->last);
        else if (in->log_count == 0) finding(what, "returned NULL without logging why (case %d)", variant);
        return;
    }
    if (valid == 0) {
        finding(what, "accepted an invalid call (case %d)", variant);
        F.FreeInstance(in->c); /* not driven on: what it would allow is not modelled */
        in->c = NULL;
        return;
    }
    instantiated(in, 0);
}

/* fmi3DoStep from the instance's time (now and then another) by a step good or bad, each
   output now and then NULL. */
static void do_step3(Inst *in) {
    static const double steps[] = {0.01, 0.05, 0.1, 0.001, 1.0, 10.0, 1e3, 1e308, 1e-300,
                                   0.0, -0.1, NAN, INFINITY, -INFINITY, 1e-12, 0.5, -1e-300,
                                   1e300};
    double h = steps[pick(4) == 0 ? pick((int)(sizeof steps / sizeof *steps)) : pick(4)];
    double t = in->time_known && pick(10) ? in->time
             : pick(2) || !in->time_known ? nasty_real(NULL) : in->time + 0.01;
    fmi3Boolean event = 1, terminate = 1, early = 1;
    fmi3Float64 last = NAN;
    int null = pick(24);
    fmi3Status s;
    begin(in);
    s = G.DoStep(in->c, t, h, pick(2), null == 0 ? NULL : &event, null == 1 ? NULL : &terminate,
                 null == 2 ? NULL : &early, null == 3 ? NULL : &last);
    end(in, "fmi3DoStep", S_STEP, s);
    if (s <= fmi2Warning) {
        if (!isfinite(t + h)) finding("fmi3DoStep", "accepted a step from %g by %g", t, h);
        if (!(h > 0)) finding("fmi3DoStep", "accepted the step %g", h);
        if (null != 0 && event) finding("fmi3DoStep", "eventHandlingNeeded without Event Mode");
        if (null != 2 && early) finding("fmi3DoStep", "earlyReturn from an FMU that never returns early");
        if (null != 3 && last != t + h)
            finding("fmi3DoStep", "lastSuccessfulTime %.17g after a full step to %.17g", last, t + h);
        in->time = t + h;
        in->time_known = 1;
        check_all_reals3(in, "fmi3DoStep");
    } else if (s == fmi2Discard) {
        in->time_known = null != 3 && isfinite(last);
        in->time = last;
    } else if (s == fmi2Error && !strstr(in->last, "illegal call sequence"))
        in->possible |= S_ERROR;
}

/* fmi3GetString / fmi3SetString on 1-3 references (mostly not Strings), nValues mostly right. */
static void strings3(Inst *in) {
    fmi3ValueReference vrs[3];
    const char *text[4] = {"text", "", "x", NULL};
    const Var *var;
    int n = 1 + pick(3), set = pick(2), i;
    size_t nv = pick(10) ? (size_t)n : (size_t)n + 1 - (size_t)pick(3);
    fmi3Status s;
    for (i = 0; i < n; i++) vrs[i] = some_vr('S', &var);
    if (pick(10) == 0) text[0] = NULL;
    begin(in);
    s = set ? G.SetString(in->c, vrs, (size_t)n, text, nv) : G.GetString(in->c, vrs, (size_t)n, text, nv);
    end(in, set ? "fmi3SetString" : "fmi3GetString", set ? ME3_SETTABLE | S_STEP : ME3_GETTABLE | S_STEP, s);
    if (s <= fmi2Warning && nv != (size_t)n)
        finding(set ? "fmi3SetString" : "fmi3GetString", "accepted nValues = %zu for %d", nv, n);
    if (!set && s == fmi2OK)
        for (i = 0; i < n; i++)
            if (!text[i] || strlen(text[i]) > 1000000) finding("fmi3GetString", "bad string");
    if (s == fmi2Error && !strstr(in->last, "illegal call sequence") &&
        (in->possible & (S_INIT | S_STEP)))
        in->possible |= S_ERROR;
}

/* A call the FMUs' Co-Simulation refuses in every state (`which`): Event Mode's, and the
   getters and setters of the types they declare no variable of. */
static void refused3(Inst *in, int which) {
    static const char *const names[] = {"fmi3EnterStepMode", "fmi3EnterEventMode",
                                        "fmi3EvaluateDiscreteStates", "fmi3GetFloat32",
                                        "fmi3SetInt8", "fmi3GetUInt64", "fmi3SetInt64",
                                        "fmi3GetBinary", "fmi3GetClock",
                                        "fmi3GetOutputDerivatives"};
    fmi3ValueReference vr = (fmi3ValueReference)pick((int)max_vr + 2);
    float f = 0;
    int8_t i8 = -3;
    uint64_t u64 = 0;
    int64_t i64 = -3;
    size_t size = 0;
    const unsigned char *bytes = NULL;
    fmi3Boolean clock = 0;
    fmi3Int32 order = 1;
    fmi3Float64 x = 0;
    fmi3Status s;
    begin(in);
    switch (which) {
    case 0: s = G.EnterStepMode(in->c); break;
    case 1: s = ME.EnterEventMode(in->c); break;
    case 2: s = G.EvaluateDiscreteStates(in->c); break;
    case 3: s = G.GetFloat32(in->c, &vr, 1, &f, 1); break;
    case 4: s = G.SetInt8(in->c, &vr, 1, &i8, 1); break;
    case 5: s = G.GetUInt64(in->c, &vr, 1, &u64, 1); break;
    case 6: s = G.SetInt64(in->c, &vr, 1, &i64, 1); break;
    case 7: s = G.GetBinary(in->c, &vr, 1, &size, &bytes, 1); break;
    case 8: s = G.GetClock(in->c, &vr, 1, &clock); break;
    default: s = G.GetOutputDerivatives(in->c, &vr, 1, &order, &x, 1); break;
    }
    end(in, names[which], which < 3 && cs_event_mode ? -1 : 0, s);
}

/* FMU states the instance did not create: another instance's, an address that is none, a
   non-state's or random bytes deserialized. */
static void foreign_states3(Inst *in) {
    fmi3Status s;
    Inst *other = &inst[pick(NINST)];
    if (pick(2)) {
        int theirs = other != in && other->c && other->nstates;
        fmi3FMUState st = theirs ? other->states[0] : (fmi3FMUState)(uintptr_t)0x1000;
        begin(in);
        s = G.SetFMUState(in->c, st);
        end(in, "fmi3SetFMUState", ANY_LIVE, s);
        if (s <= fmi2Warning) finding("fmi3SetFMUState", "accepted a state it did not create");
        return;
    }
    {
        static const char not_a_state[] = "not a serialized FMU state";
        unsigned char random[64];
        int is_text = pick(2);
        size_t len = is_text ? sizeof not_a_state : 1 + (size_t)pick(64), k;
        fmi3FMUState st = NULL;
        for (k = 0; k < len && !is_text; k++) random[k] = (unsigned char)pick(256);
        begin(in);
        s = G.DeserializeFMUState(in->c, is_text ? (const unsigned char *)not_a_state : random,
                                  len, pick(20) ? &st : NULL);
        end(in, "fmi3DeserializeFMUState", ANY_LIVE, s);
        if (s <= fmi2Warning) {
            finding("fmi3DeserializeFMUState", "accepted %s bytes", is_text ? "a text's" : "random");
            if (st) {
                begin(in);
                end(in, "fmi3FreeFMUState", ANY_LIVE, G.FreeFMUState(in->c, &st));
            }
        }
    }
}

/* Calls with a NULL instance (each fmi3Error, nothing touched) and fmi3SetDebugLogging. */
static void null_and_logging3(Inst *in) {
    if (pick(2)) {
        const char *cats[2] = {"logStatusError", pick(2) ? "noSuchCategory" : "logAll"};
        fmi3Status s;
        begin(in);
        s = G.SetDebugLogging(in->c, pick(2), 1 + (size_t)pick(2), pick(20) ? cats : NULL);
        end(in, "fmi3SetDebugLogging", ANY_LIVE, s);
        return;
    }
    {
        fmi3Float64 x = 0;
        fmi3ValueReference vr = 0;
        fmi3FMUState st = NULL;
        double ms = now_ms();
        calls_total++;
        call_no++;
        if (G.DoStep(NULL, 0, 0.1, 0, NULL, NULL, NULL, NULL) != fmi2Error ||
            G.GetFloat64(NULL, &vr, 1, &x, 1) != fmi2Error ||
            G.EnterInitializationMode(NULL, 0, 0, 0, 0, 0) != fmi2Error ||
            G.GetFMUState(NULL, &st) != fmi2Error || G.EnterStepMode(NULL) != fmi2Error)
            finding("NULL instance", "not fmi3Error");
        F.FreeInstance(NULL);
        if (now_ms() - ms > bound_ms) finding("NULL instance", "slow");
    }
}

/* One Co-Simulation call: fmi3DoStep (0-49), strings (50-57), a refused call (58-69),
   foreign states (70-79), NULL instances and logging (80-84), fmi3ExitInitializationMode
   (85-92), fmi3Terminate or fmi3Reset (93-96), fmi3FreeInstance (97-99); an instance known to
   be Terminated is reset one time in three (else most calls would find it there). */
static void cs3_call(Inst *in) {
    int op = pick(100);
    if (in->possible == S_TERMINATED && pick(3) == 0) end_or_reset3(in, 1);
    else if (op < 50) do_step3(in);
    else if (op < 58) strings3(in);
    else if (op < 70) refused3(in, pick(10));
    else if (op < 80) foreign_states3(in);
    else if (op < 85) null_and_logging3(in);
    else if (op < 93) {
        fmi3Status s = plain_call(in, G.ExitInitializationMode, "fmi3ExitInitializationMode", S_INIT);
        if (s <= fmi2Warning) {
            in->possible = S_STEP;
            check_all_reals3(in, "fmi3ExitInitializationMode");
        } else if (s == fmi2Error && !strstr(in->last, "illegal call sequence"))
            in->possible |= S_ERROR;
    } else if (op < 97) end_or_reset3(in, pick(2));
    else free_instance(in);
}

static void random_call3(Inst *in) {
    fmi3Status s;
    int op;
    if (!in->c) {
        if (cs_interface) instantiate3cs(in);
        else instantiate3(in);
        return;
    }
    if (pick(3) == 0 && me_advance(in)) return;
    if (cs_interface && pick(2)) {
        cs3_call(in);
        return;
    }
    op = pick(120);
    if (op < 2) {
        free_instance(in);
        return;
    }
    if (op < 4) {
        enter_init3(in);
        return;
    }
    if (op < 8) {
        end_or_reset3(in, op >= 6);
        return;
    }
    if (op < 88) {
        if (cs_interface && pick(4)) { /* on a Co-Simulation instance, a quarter of them */
            cs3_call(in);
            return;
        }
        me_shared_call(in, op - 8);
        return;
    }
    if (op < 89) { /* fmi3EvaluateDiscreteStates: the FMUs do not provide it, refused anywhere */
        plain_call(in, G.EvaluateDiscreteStates, "fmi3EvaluateDiscreteStates", 0);
        return;
    }
    if (op < 92) { /* fmi3GetNumberOfEventIndicators / ContinuousStates */
        int which = pick(2);
        size_t count = 12345;
        int null = pick(20) == 0;
        begin(in);
        s = G.GetNumber[which](in->c, null ? NULL : &count);
        end(in, which ? "fmi3GetNumberOfContinuousStates" : "fmi3GetNumberOfEventIndicators",
            ANY_LIVE, s);
        if (s <= fmi2Warning && null) finding("fmi3GetNumberOf*", "accepted a NULL size");
        if (s == fmi2OK && !null && count != (size_t)(which ? nx : nz))
            finding("fmi3GetNumberOf*", "%zu, the model description says %d", count, which ? nx : nz);
        return;
    }
    if (op < 100) { /* fmi3UpdateDiscreteStates, each output sometimes NULL */
        fmi3Boolean flag[5] = {0, 0, 0, 0, 0};
        fmi3Float64 next = 0;
        int null = pick(14);
        begin(in);
        s = G.UpdateDiscreteStates(in->c, null == 0 ? NULL : &flag[0], null == 1 ? NULL : &flag[1],
                                   null == 2 ? NULL : &flag[2], null == 3 ? NULL : &flag[3],
                                   null == 4 ? NULL : &flag[4], null == 5 ? NULL : &next);
        me_updated(in, "fmi3UpdateDiscreteStates", s, flag[4] && null != 5, next);
        return;
    }
    if (op < 106) { /* fmi3GetDirectionalDerivative or fmi3GetAdjointDerivative (the seed over
                       the unknowns, the result over the knowns): wrong nSeed / nSensitivity
                       now and then */
        fmi3ValueReference u[8], k[8];
        fmi3Float64 seed[8], seeds_at[65], out[65];
        size_t nu, nk, nseed, nsens, seeds, results, elements[2] = {0, 0}, i;
        int null = pick(20), adjoint = pick(3) == 0;
        const char *what = adjoint ? "fmi3GetAdjointDerivative" : "fmi3GetDirectionalDerivative";
        directional_args(u, &nu, k, &nk, seed);
        for (i = 0; i < nu; i++) elements[0] += (size_t)count_of(u[i]); /* arrays: elements */
        for (i = 0; i < nk; i++) elements[1] += (size_t)count_of(k[i]);
        seeds = elements[adjoint ? 0 : 1];
        results = elements[adjoint ? 1 : 0];
        if (seeds > 64 || results > 64) return;
        for (i = 0; i < seeds; i++) seeds_at[i] = seed[i % nk];
        nseed = pick(10) ? seeds : seeds - 1;
        nsens = pick(10) ? results : results + 1;
        begin(in);
        s = (adjoint ? G.GetAdjointDerivative : G.GetDirectionalDerivative)(
            in->c, null == 0 ? NULL : u, nu, k, nk, null == 1 ? NULL : seeds_at, nseed,
            null == 2 ? NULL : out, nsens);
        end(in, what, ME3_GETTABLE | S_STEP, s);
        if (s <= fmi2Warning && null < 3) finding(what, "accepted a NULL array");
        if (s <= fmi2Warning && (nseed != seeds || nsens != results))
            finding(what, "accepted nSeed %zu for %zu seeds, nSensitivity %zu for %zu results",
                    nseed, seeds, nsens, results);
        if (s == fmi2OK && null >= 3) me_finite(what, out, results);
        if (s == fmi2Error && !strstr(in->last, "illegal call sequence")) in->possible |= S_ERROR;
        return;
    }
    if (op < 114) {
        values3(in, pick(2));
        return;
    }
    states3(in);
}

/* ---- loading ------------------------------------------------------------------------- */
static int read_manifest(const char *path) {
    FILE *f = fopen(path, "r");
    char line[2048];
    int cap = 64;
    if (!f) return 0;
    vars = calloc(cap, sizeof *vars);
    while (fgets(line, sizeof line, f)) {
        char *fields[8];
        int nf = 0;
        char *p = line, *tab;
        line[strcspn(line, "\n")] = 0;
        while (nf < 8) {
            fields[nf++] = p;
            tab = strchr(p, '\t');
            if (!tab) break;
            *tab = 0;
            p = tab + 1;
        }
        if (!strcmp(fields[0], "label") && nf > 1) snprintf(label, sizeof label, "%s", fields[1]);
        else if (!strcmp(fields[0], "id") && nf > 1) snprintf(model_id, sizeof model_id, "%s", fields[1]);
        else if (!strcmp(fields[0], "guid") && nf > 1) snprintf(guid, sizeof guid, "%s", fields[1]);
        else if (!strcmp(fields[0], "library") && nf > 1) snprintf(library, sizeof library, "%s", fields[1]);
        else if (!strcmp(fields[0], "resources") && nf > 1) snprintf(resources, sizeof resources, "%s", fields[1]);
        else if (!strcmp(fields[0], "me") && nf > 1) model_exchange = atoi(fields[1]);
        else if (!strcmp(fields[0], "version") && nf > 1) version = atoi(fields[1]);
        else if (!strcmp(fields[0], "interface") && nf > 1) cs_interface = !strcmp(fields[1], "cs");
        else if (!strcmp(fields[0], "cs_event_mode") && nf > 1) cs_event_mode = atoi(fields[1]);
        else if (!strcmp(fields[0], "cs_intermediate") && nf > 1) cs_intermediate = atoi(fields[1]);
        else if (!strcmp(fields[0], "count") && nf > 2) {
            unsigned vr = (unsigned)strtoul(fields[1], NULL, 10);
            if (vr < 4096) counts[vr] = atoi(fields[2]);
        }
        else if (!strcmp(fields[0], "nz") && nf > 1) nz = atoi(fields[1]);
        else if (!strcmp(fields[0], "state") && nf > 2 && nx < 64) {
            state_vr[nx] = (fmi2ValueReference)strtoul(fields[1], NULL, 10);
            der_vr[nx++] = (fmi2ValueReference)strtoul(fields[2], NULL, 10);
        }
        else if (!strcmp(fields[0], "var") && nf == 8) {
            Var *v;
            if (nvars == cap) vars = realloc(vars, sizeof *vars * (cap *= 2));
            v = &vars[nvars++];
            memset(v, 0, sizeof *v);
            v->vr = (unsigned)strtoul(fields[1], NULL, 10);
            v->type = fields[2][0];
            snprintf(v->causality, sizeof v->causality, "%s", fields[3]);
            snprintf(v->variability, sizeof v->variability, "%s", fields[4]);
            if (strcmp(fields[5], "-")) { v->has_min = 1; v->min = strtod(fields[5], NULL); }
            if (strcmp(fields[6], "-")) { v->has_max = 1; v->max = strtod(fields[6], NULL); }
            snprintf(v->name, sizeof v->name, "%s", fields[7]);
            if (v->vr > max_vr) max_vr = v->vr;
        }
    }
    fclose(f);
    return nvars > 0 && model_id[0] && library[0];
}

#define LOAD(field, symbol)                                                                   \
    do {                                                                                      \
        *(void **)(&F.field) = dlsym(lib, symbol);                                            \
        if (!F.field) { fprintf(stderr, "%s: missing %s\n", library, symbol); return 0; }     \
    } while (0)

/* Loads the Model Exchange functions FMI version `fmi` ("fmi2", "fmi3") shares with the other
   into ME, with their names (the derivatives' function: fmi2GetDerivatives,
   fmi3GetContinuousStateDerivatives); false, said on stderr, when one is missing. */
static int load_prefixed(void *lib, const char *fmi, const char *const *what, void ***slots, int n,
                         char (*names)[64]);
static int me_load(void *lib, const char *fmi, const char *derivatives, void (*enter_init)(Inst *),
                   void (*check_all)(Inst *, const char *)) {
    static char names[10][64];
    const char *const what[10] = {"GetContinuousStates", derivatives, "GetEventIndicators",
                                  "GetNominalsOfContinuousStates", "SetTime",
                                  "SetContinuousStates", "EnterEventMode",
                                  "EnterContinuousTimeMode", "ExitInitializationMode",
                                  "CompletedIntegratorStep"};
    const char **named[10] = {&ME.array_names[0], &ME.array_names[1], &ME.array_names[2],
                              &ME.array_names[3], &ME.set_time, &ME.set_states,
                              &ME.enter_event, &ME.enter_continuous, &ME.exit_init,
                              &ME.completed};
    void **functions[10] = {(void **)&ME.GetArray[0], (void **)&ME.GetArray[1],
                            (void **)&ME.GetArray[2], (void **)&ME.GetArray[3],
                            (void **)&ME.SetTime, (void **)&ME.SetContinuousStates,
                            (void **)&ME.EnterEventMode, (void **)&ME.EnterContinuousTimeMode,
                            (void **)&ME.ExitInitializationMode,
                            (void **)&ME.CompletedIntegratorStep};
    if (!load_prefixed(lib, fmi, what, functions, 10, names)) return 0;
    for (int k = 0; k < 10; k++) *named[k] = names[k];
    ME.enter_init = enter_init;
    ME.check_all_reals = check_all;
    return 1;
}

/* fmi3CompletedIntegratorStep with FMI 2.0's argument types (for ME.CompletedIntegratorStep). */
static fmi2Status completed3(fmi2Component c, fmi2Boolean no_set_state, fmi2Boolean *event,
                             fmi2Boolean *terminate) {
    fmi3Boolean e = 0, t = 0;
    fmi3Status s = G.CompletedIntegratorStep(c, no_set_state != 0, event ? &e : NULL,
                                             terminate ? &t : NULL);
    if (event) *event = e;
    if (terminate) *terminate = t;
    return s;
}

/* dlsym of the `n` functions `fmi` + what[k] ("fmi3" + "Reset") into *slots[k], their names
   kept in names[k] when `names` is not NULL; false, said on stderr, when one is missing. */
static int load_prefixed(void *lib, const char *fmi, const char *const *what, void ***slots, int n,
                         char (*names)[64]) {
    char name[64];
    for (int k = 0; k < n; k++) {
        snprintf(name, sizeof name, "%s%s", fmi, what[k]);
        if (names) snprintf(names[k], sizeof names[k], "%s", name);
        *slots[k] = dlsym(lib, name);
        if (!*slots[k]) {
            fprintf(stderr, "%s: missing %s\n", library, name);
            return 0;
        }
    }
    return 1;
}

static int load3(void *lib) {
    const char *const what[] = {
        "InstantiateModelExchange", "InstantiateCoSimulation", "FreeInstance",
        "EnterInitializationMode", "ExitInitializationMode", "Terminate", "Reset", "GetFloat64",
        "GetInt32", "GetBoolean", "SetFloat64", "SetInt32", "SetBoolean", "GetFMUState",
        "SetFMUState", "FreeFMUState", "SerializedFMUStateSize", "SerializeFMUState",
        "DeserializeFMUState", "GetNumberOfEventIndicators", "GetNumberOfContinuousStates",
        "UpdateDiscreteStates", "CompletedIntegratorStep", "GetDirectionalDerivative",
        "GetAdjointDerivative", "EvaluateDiscreteStates", "DoStep", "EnterStepMode", "GetString",
        "SetString", "SetDebugLogging", "GetFloat32", "SetInt8", "GetUInt64", "SetInt64",
        "GetBinary", "GetClock", "GetOutputDerivatives"};
    void **slots[] = {
        (void **)&G.InstantiateModelExchange, (void **)&G.InstantiateCoSimulation,
        (void **)&F.FreeInstance, (void **)&G.EnterInitializationMode,
        (void **)&G.ExitInitializationMode, (void **)&G.Terminate, (void **)&G.Reset,
        (void **)&G.GetFloat64, (void **)&G.GetInt32, (void **)&G.GetBoolean,
        (void **)&G.SetFloat64, (void **)&G.SetInt32, (void **)&G.SetBoolean,
        (void **)&G.GetFMUState, (void **)&G.SetFMUState, (void **)&G.FreeFMUState,
        (void **)&G.SerializedFMUStateSize, (void **)&G.SerializeFMUState,
        (void **)&G.DeserializeFMUState, (void **)&G.GetNumber[0], (void **)&G.GetNumber[1],
        (void **)&G.UpdateDiscreteStates, (void **)&G.CompletedIntegratorStep,
        (void **)&G.GetDirectionalDerivative, (void **)&G.GetAdjointDerivative,
        (void **)&G.EvaluateDiscreteStates, (void **)&G.DoStep, (void **)&G.EnterStepMode,
        (void **)&G.GetString, (void **)&G.SetString, (void **)&G.SetDebugLogging,
        (void **)&G.GetFloat32, (void **)&G.SetInt8, (void **)&G.GetUInt64, (void **)&G.SetInt64,
        (void **)&G.GetBinary, (void **)&G.GetClock, (void **)&G.GetOutputDerivatives};
    if (!load_prefixed(lib, "fmi3", what, slots, (int)(sizeof slots / sizeof *slots), NULL) ||
        !me_load(lib, "fmi3", "GetContinuousStateDerivatives", enter_init3, check_all_reals3))
        return 0;
    ME.CompletedIntegratorStep = completed3;
    return 1;
}

static int load(void) {
    void *lib = dlopen(library, RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 0; }
    if (version == 3) return load3(lib);
    LOAD(Instantiate, "fmi2Instantiate"); LOAD(FreeInstance, "fmi2FreeInstance");
    LOAD(SetDebugLogging, "fmi2SetDebugLogging"); LOAD(SetupExperiment, "fmi2SetupExperiment");
    LOAD(EnterInitializationMode, "fmi2EnterInitializationMode");
    LOAD(ExitInitializationMode, "fmi2ExitInitializationMode");
    LOAD(Terminate, "fmi2Terminate"); LOAD(Reset, "fmi2Reset");
    LOAD(GetReal, "fmi2GetReal"); LOAD(GetInteger, "fmi2GetInteger");
    LOAD(GetBoolean, "fmi2GetBoolean"); LOAD(GetString, "fmi2GetString");
    LOAD(SetReal, "fmi2SetReal"); LOAD(SetInteger, "fmi2SetInteger");
    LOAD(SetBoolean, "fmi2SetBoolean"); LOAD(SetString, "fmi2SetString");
    LOAD(GetFMUstate, "fmi2GetFMUstate"); LOAD(SetFMUstate, "fmi2SetFMUstate");
    LOAD(FreeFMUstate, "fmi2FreeFMUstate");
    LOAD(SerializedFMUstateSize, "fmi2SerializedFMUstateSize");
    LOAD(SerializeFMUstate, "fmi2SerializeFMUstate");
    LOAD(DeSerializeFMUstate, "fmi2DeSerializeFMUstate");
    LOAD(DoStep, "fmi2DoStep"); LOAD(CancelStep, "fmi2CancelStep");
    LOAD(GetStatus, "fmi2GetStatus"); LOAD(GetRealStatus, "fmi2GetRealStatus");
    LOAD(GetIntegerStatus, "fmi2GetIntegerStatus"); LOAD(GetBooleanStatus, "fmi2GetBooleanStatus");
    LOAD(GetStringStatus, "fmi2GetStringStatus");
    if (!model_exchange) return 1;
    if (!me_load(lib, "fmi2", "GetDerivatives", enter_init2, check_all_reals)) return 0;
    LOAD(GetDirectionalDerivative, "fmi2GetDirectionalDerivative");
    LOAD(NewDiscreteStates, "fmi2NewDiscreteStates");
    return 1;
}

int main(int argc, char **argv) {
    long calls, k;
    unsigned long long seed;
    int i;
    if (argc < 4) {
        fprintf(stderr, "usage: driver MANIFEST SEED CALLS [BOUND_MS [FOREIGN_STATE_FILE [DUMP_FILE]]]\n");
        return 2;
    }
    seed = strtoull(argv[2], NULL, 10);
    calls = strtol(argv[3], NULL, 10);
    if (argc > 4) bound_ms = strtod(argv[4], NULL);
    if (argc > 5) {
        FILE *f = fopen(argv[5], "rb");
        if (f) {
            foreign = malloc(1 << 20);
            foreign_len = fread(foreign, 1, 1 << 20, f);
            fclose(f);
        }
    }
    if (argc > 6) dump_path = argv[6];
    trace = getenv("MISUSE_TRACE") != NULL;
    if (!read_manifest(argv[1])) { fprintf(stderr, "%s: cannot read the manifest\n", argv[1]); return 2; }
    if (!load()) return 2;
    hang_seconds = (unsigned)(bound_ms / 1000.0 * 10.0) + 1;
    signal(SIGALRM, on_alarm);
    rng = seed ^ 0x53505552494F0000ULL;
    if (!label[0]) snprintf(label, sizeof label, "%s", model_id);
    for (i = 0; i < (int)strlen(label); i++) rng = rng * 31 + (unsigned char)label[i];
    for (k = 0; k < calls; k++) {
        Inst *in = &inst[pick(5) == 0 ? pick(NINST) : 0];
        if (in->c && in->possible == S_FATAL) free_instance(in);
        if (version == 3) random_call3(in);
        else random_call(in);
    }
    for (i = 0; i < NINST; i++)
        if (inst[i].c) free_instance(&inst[i]);
    if (dump_path && own_len) {
        FILE *f = fopen(dump_path, "wb");
        if (f) { fwrite(own_bytes, 1, own_len, f); fclose(f); }
    }
    printf("%-34s %8ld calls  %3ld findings  slowest %.1f ms (%s)", label, calls_total,
           findings, slowest_ms, slowest_what);
    if (model_exchange && !cs_interface) printf("  %ld on Model Exchange instances", calls_me);
    printf("\n");
    free(own_bytes);
    free(foreign);
    free(vars);
    return findings ? 1 : 0;
}
