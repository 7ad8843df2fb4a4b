/* The allocation driver: counts the heap allocations of one FMU (FMI 2.0 or 3.0 Co-Simulation)
 * through its C ABI, and measures what one instance costs.
 *
 *   driver MANIFEST STEPS REPEATS
 *
 * MANIFEST is written by manifest.py. The driver defines malloc, calloc, realloc, free,
 * posix_memalign, aligned_alloc and memalign itself (forwarding to glibc's __libc_*), so
 * every allocation of the FMU library it dlopens -- Rust's System allocator included -- comes
 * through it; it is linked with -rdynamic so the library binds to these.
 *
 * 1. Instance cost: instantiates, sets every parameter to its start value and initialises
 *    REPEATS instances one after the other (after one warm-up instance: what a process does
 *    once per configuration is not an instance's cost), each time measuring the heap bytes
 *    it holds when initialised (malloc_usable_size of what it allocated minus what it freed)
 *    and the time of instantiate + set parameters + initialise (the median is printed).
 * 2. Step phase: one instance, initialised; then STEPS times: set every input (its start,
 *    nudged within its bounds), DoStep, read every output (Real/Integer/Boolean, one call
 *    per type as a master does). Every malloc/calloc/realloc/aligned allocation and every free
 *    during these calls is counted.
 *
 * Prints one line:
 *   <label> fmi<v>: <steps> steps, <n> allocations (<malloc>/<calloc>/<realloc>/<aligned>),
 *   <f> frees; instance <bytes> B, instantiate+initialise <median> ms
 * Exit status: 0 no allocation and no free in the step phase, 1 some, 2 usage or FMU error.
 *
 * Timing mode (what scripts/bench measures as the direct C ABI path):
 *
 *   driver MANIFEST STEPS REPEATS --time BATCHES [--amplitude A] [--outliers] [--step H]
 *
 * One instance, initialised; the Real inputs of 1024 steps are formed before any timing, as
 * the benchmark forms them (input i at step k: its start + A sin(0.05 (i+1) k), + 3 on 5 % of
 * the samples with --outliers; A defaults to 0.1), and cycled; the communication step is H
 * with --step H, else the manifest's. Each step sets every Real input
 * (one fmi2SetReal / fmi3SetFloat64), calls DoStep and reads every output (one call per type).
 * After one warm-up batch, BATCHES batches of STEPS steps are timed and the median ns per step
 * is printed as `<label> fmi<v>: <median> ns per step (median of <BATCHES> batches of <STEPS>
 * steps)`. With BATCHES 0 the batches are driven from stdin instead: a line with a step count
 * runs that many steps and answers with one line, the ns per step (what lets the benchmark
 * interleave them with its own); end of input ends. REPEATS is ignored. The malloc counters
 * above stay in the process (they interpose malloc globally) but are switched off, and no
 * call of the timed loop allocates (the allocation test checks it), so they cost nothing in it.
 * Exit status: 0, or 2 usage or FMU error.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <malloc.h>
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- the allocation counter ------------------------------------------------------------ */
extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void *__libc_memalign(size_t, size_t);
extern void __libc_free(void *);

static int counting;   /* count calls (step phase) */
static int measuring;  /* track live bytes (instance cost) */
static long n_malloc, n_calloc, n_realloc, n_aligned, n_free;
static long long live;

static void *noted(void *p, long *counter) {
    if (p && counting) ++*counter;
    if (p && measuring) live += (long long)malloc_usable_size(p);
    return p;
}
static void before_free(void *p) {
    if (!p) return;
    if (counting) ++n_free;
    if (measuring) live -= (long long)malloc_usable_size(p);
}
void *malloc(size_t n) { return noted(__libc_malloc(n), &n_malloc); }
void *calloc(size_t n, size_t size) { return noted(__libc_calloc(n, size), &n_calloc); }
void *realloc(void *p, size_t n) {
    before_free(p);
    if (p && counting) --n_free; /* a realloc is one event, counted as a realloc */
    return noted(__libc_realloc(p, n), &n_realloc);
}
void free(void *p) {
    before_free(p);
    __libc_free(p);
}
void *memalign(size_t align, size_t n) { return noted(__libc_memalign(align, n), &n_aligned); }
void *aligned_alloc(size_t align, size_t n) { return memalign(align, n); }
int posix_memalign(void **out, size_t align, size_t n) {
    void *p = memalign(align, n);
    if (!p) return 12; /* ENOMEM */
    *out = p;
    return 0;
}

/* ---- the manifest ---------------------------------------------------------------------- */
typedef struct {
    unsigned vr;
    char type; /* R I B S */
    char causality[24];
    char variability[16];
    int count;
    int has_start, has_min, has_max;
    double min, max;
    double *start; /* per element */
} Var;

static double parse_value(const char *text) {
    return !strcmp(text, "true") ? 1 : !strcmp(text, "false") ? 0 : atof(text);
}

static char label[128], model_id[128], token[128], library[1024], resources[1200];
static int version;
static double step = 0.01;
static Var *vars;
static int nvars;

static void read_manifest(const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) { fprintf(stderr, "cannot open %s\n", path); exit(2); }
    static char line[4096];
    int cap = 0;
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\n")] = 0;
        char *key = strtok(line, "\t"), *rest = strtok(NULL, "");
        if (!key || !rest) continue;
        if (!strcmp(key, "label")) snprintf(label, sizeof label, "%s", rest);
        else if (!strcmp(key, "version")) version = atoi(rest);
        else if (!strcmp(key, "id")) snprintf(model_id, sizeof model_id, "%s", rest);
        else if (!strcmp(key, "token")) snprintf(token, sizeof token, "%s", rest);
        else if (!strcmp(key, "library")) snprintf(library, sizeof library, "%s", rest);
        else if (!strcmp(key, "resources")) snprintf(resources, sizeof resources, "%s", rest);
        else if (!strcmp(key, "step")) step = atof(rest);
        else if (!strcmp(key, "var")) {
            if (nvars == cap) {
                cap = cap ? 2 * cap : 64;
                vars = realloc(vars, (size_t)cap * sizeof *vars);
            }
            Var *v = &vars[nvars++];
            memset(v, 0, sizeof *v);
            char *field[8];
            field[0] = strtok(rest, "\t");
            for (int i = 1; i < 8; i++) field[i] = strtok(NULL, "\t");
            if (!field[7]) { fprintf(stderr, "bad var line\n"); exit(2); }
            v->vr = (unsigned)strtoul(field[0], NULL, 10);
            v->type = field[1][0];
            snprintf(v->causality, sizeof v->causality, "%s", field[2]);
            snprintf(v->variability, sizeof v->variability, "%s", field[3]);
            v->count = atoi(field[4]);
            v->start = calloc((size_t)v->count + 1, sizeof *v->start);
            if ((v->has_start = strcmp(field[5], "-") != 0)) {
                /* Space-separated element starts; the last one repeats. */
                char *p = field[5];
                for (int k = 0; k < v->count; k++) {
                    char *end = p + strcspn(p, " ");
                    char saved = *end;
                    *end = 0;
                    v->start[k] = parse_value(p);
                    *end = saved;
                    if (saved) p = end + 1;
                }
            }
            if ((v->has_min = strcmp(field[6], "-") != 0)) v->min = atof(field[6]);
            if ((v->has_max = strcmp(field[7], "-") != 0)) v->max = atof(field[7]);
        }
    }
    fclose(f);
    if (version != 2 && version != 3) { fprintf(stderr, "unknown FMI version\n"); exit(2); }
}

/* ---- the FMU ---------------------------------------------------------------------------- */
typedef int Status;
typedef void *Instance;
static void *lib;

static void *sym(const char *name) {
    void *p = dlsym(lib, name);
    if (!p) { fprintf(stderr, "%s: missing symbol %s\n", label, name); exit(2); }
    return p;
}

static void log_fmi2(void *env, const char *name, Status status, const char *category,
                 const char *message, ...) {
    (void)env;
    int was = counting;
    counting = 0;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s %d %s] ", name ? name : "?", status, category ? category : "?");
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
    counting = was;
}
static void log_fmi3(void *env, Status status, const char *category, const char *message) {
    (void)env;
    int was = counting;
    counting = 0;
    fprintf(stderr, "[%d %s] %s\n", status, category ? category : "?", message);
    counting = was;
}

/* fmi2CallbackFunctions: logger, allocateMemory, freeMemory, stepFinished,
 * componentEnvironment -- five pointers. */
static void *callbacks2[5];

/* Per type (R I B): the value references and the number of values of the parameters, of
 * the inputs and of the outputs, and a buffer for the values. */
enum { PARAMETERS, INPUTS, OUTPUTS, GROUPS };
static const char TYPES[3] = {'R', 'I', 'B'};
typedef struct {
    unsigned *vrs;
    int nvr, nvalues;
    Var **var; /* per value: its variable */
    int *element; /* per value: its index in the variable */
    double *real;
    int *integer; /* fmi2Integer, fmi2Boolean, fmi3Int32 */
    bool *boolean; /* fmi3Boolean */
} Group;
static Group groups[GROUPS][3];

static int group_of(const Var *v) {
    if (!strcmp(v->causality, "parameter")) return PARAMETERS;
    if (!strcmp(v->causality, "input")) return INPUTS;
    if (!strcmp(v->causality, "output")) return OUTPUTS;
    return -1;
}

static void build_groups(void) {
    for (int g = 0; g < GROUPS; g++)
        for (int t = 0; t < 3; t++) {
            Group *G = &groups[g][t];
            G->vrs = calloc((size_t)nvars + 1, sizeof *G->vrs);
            int total = 0;
            for (int i = 0; i < nvars; i++)
                if (group_of(&vars[i]) == g && vars[i].type == TYPES[t]) total += vars[i].count;
            G->var = calloc((size_t)total + 1, sizeof *G->var);
            G->element = calloc((size_t)total + 1, sizeof *G->element);
            G->real = calloc((size_t)total + 1, sizeof *G->real);
            G->integer = calloc((size_t)total + 1, sizeof *G->integer);
            G->boolean = calloc((size_t)total + 1, sizeof *G->boolean);
            for (int i = 0; i < nvars; i++) {
                Var *v = &vars[i];
                if (group_of(v) != g || v->type != TYPES[t]) continue;
                if (g != OUTPUTS && !v->has_start) continue;
                G->vrs[G->nvr++] = v->vr;
                for (int k = 0; k < v->count; k++) {
                    G->element[G->nvalues] = k;
                    G->var[G->nvalues++] = v;
                }
            }
        }
}

/* The value of the k-th element of group G at step n: its start, nudged within its bounds
 * for Real inputs (so the model's arithmetic sees changing inputs). */
static void fill(Group *G, int t, int nudge, long n) {
    for (int k = 0; k < G->nvalues; k++) {
        const Var *v = G->var[k];
        double x = v->start[G->element[k]];
        if (nudge && t == 0) {
            x += 1e-3 * sin(0.1 * (double)n + k) * (fabs(x) + 1.0);
            if (v->has_min && x < v->min) x = v->min;
            if (v->has_max && x > v->max) x = v->max;
        }
        G->real[k] = x;
        G->integer[k] = (int)x;
        G->boolean[k] = x != 0;
    }
}

/* The typed get/set functions by type (R I B): FMI 2.0 (instance, vrs, nvr, values), FMI 3.0
 * (instance, vrs, nvr, values, nValues); the set ones take const values. */
typedef Status (*Call2)(Instance, const unsigned *, size_t, void *);
typedef Status (*Call3)(Instance, const unsigned *, size_t, void *, size_t);
static const char *const CALLS[2][2][3] = {
    {{"fmi2GetReal", "fmi2GetInteger", "fmi2GetBoolean"},
     {"fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean"}},
    {{"fmi3GetFloat64", "fmi3GetInt32", "fmi3GetBoolean"},
     {"fmi3SetFloat64", "fmi3SetInt32", "fmi3SetBoolean"}},
};
static void *calls[2][3]; /* [get, set][type] of the loaded version */

static struct {
    Instance (*instantiate2)(const char *, int, const char *, const char *, void *const *, int,
                             int);
    Instance (*instantiate3)(const char *, const char *, const char *, bool, bool, bool, bool,
                             const unsigned *, size_t, void *, void *, void *);
    void (*free)(Instance);
    Status (*setup2)(Instance, int, double, double, int, double);
    Status (*enter2)(Instance);
    Status (*enter3)(Instance, bool, double, double, bool, double);
    Status (*exit)(Instance), (*terminate)(Instance);
    Status (*step2)(Instance, double, double, int);
    Status (*step3)(Instance, double, double, bool, bool *, bool *, bool *, double *);
} F;

static void load(void) {
    lib = dlopen(library, RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s: %s\n", label, dlerror()); exit(2); }
    int v = version - 2;
    for (int get_set = 0; get_set < 2; get_set++)
        for (int t = 0; t < 3; t++) calls[get_set][t] = sym(CALLS[v][get_set][t]);
#define S(field, name2, name3) *(void **)&F.field = sym(v ? name3 : name2)
    S(free, "fmi2FreeInstance", "fmi3FreeInstance");
    S(exit, "fmi2ExitInitializationMode", "fmi3ExitInitializationMode");
    S(terminate, "fmi2Terminate", "fmi3Terminate");
    if (v) {
        S(instantiate3, "", "fmi3InstantiateCoSimulation");
        S(enter3, "", "fmi3EnterInitializationMode");
        S(step3, "", "fmi3DoStep");
    } else {
        S(instantiate2, "fmi2Instantiate", "");
        S(setup2, "fmi2SetupExperiment", "");
        S(enter2, "fmi2EnterInitializationMode", "");
        S(step2, "fmi2DoStep", "");
    }
#undef S
}

static void check(Status s, const char *what) {
    if (s > 1) { /* fmi2OK / fmi2Warning */
        counting = 0;
        fprintf(stderr, "%s fmi%d: %s returned status %d\n", label, version, what, s);
        exit(2);
    }
}

/* Gets (get_set 0) or sets (1) group g of every type; the inputs set at step n are nudged. */
static void exchange(Instance c, int g, int get_set, long n) {
    for (int t = 0; t < 3; t++) {
        Group *G = &groups[g][t];
        if (!G->nvr) continue;
        if (get_set) fill(G, t, g == INPUTS, n);
        /* fmi3Boolean is a bool; fmi2Boolean and the Integers are ints. */
        void *values = t == 0 ? (void *)G->real
                       : t == 2 && version == 3 ? (void *)G->boolean : (void *)G->integer;
        void *call = calls[get_set][t];
        size_t m = (size_t)G->nvr;
        Status s = version == 2 ? (*(Call2 *)&call)(c, G->vrs, m, values)
                                : (*(Call3 *)&call)(c, G->vrs, m, values, (size_t)G->nvalues);
        check(s, CALLS[version - 2][get_set][t]);
    }
}

/* Instantiates, sets the parameters, initialises. */
static Instance start(void) {
    Instance c;
    if (version == 2) {
        callbacks2[0] = (void *)log_fmi2;
        callbacks2[1] = (void *)calloc;
        callbacks2[2] = (void *)free;
        c = F.instantiate2("alloc", 1, token, resources, callbacks2, 0, 0);
        if (!c) { fprintf(stderr, "%s: fmi2Instantiate failed\n", label); exit(2); }
        exchange(c, PARAMETERS, 1, 0);
        check(F.setup2(c, 0, 0.0, 0.0, 0, 0.0), "fmi2SetupExperiment");
        check(F.enter2(c), "fmi2EnterInitializationMode");
        check(F.exit(c), "fmi2ExitInitializationMode");
    } else {
        c = F.instantiate3("alloc", token, resources, false, false, false, false, NULL, 0, NULL,
                           (void *)log_fmi3, NULL);
        if (!c) { fprintf(stderr, "%s: fmi3InstantiateCoSimulation failed\n", label); exit(2); }
        exchange(c, PARAMETERS, 1, 0);
        check(F.enter3(c, false, 0.0, 0.0, false, 0.0), "fmi3EnterInitializationMode");
        check(F.exit(c), "fmi3ExitInitializationMode");
    }
    return c;
}

static void stop(Instance c) {
    F.terminate(c);
    F.free(c);
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* ---- timing mode ----------------------------------------------------------------------- */
enum { SIGNAL_PERIOD = 1024 };
static double *signals; /* SIGNAL_PERIOD rows of the Real inputs' values */
static double timed_t;
static long timed_k;

/* The same inputs as the benchmark's importer path (input_signals in benches/src/fmus.rs): keep the
 * two formulas alike, the bench compares the paths on them. */
static void form_signals(double amplitude, int outliers) {
    Group *G = &groups[INPUTS][0];
    int n = G->nvalues;
    signals = calloc((size_t)SIGNAL_PERIOD * (size_t)n + 1, sizeof *signals);
    for (long k = 0; k < SIGNAL_PERIOD; k++)
        for (int i = 0; i < n; i++) {
            double phase = (double)k * 0.05 * (double)(i + 1);
            int outlier = outliers && (k * 7 + i) % 20 == 0;
            signals[k * n + i] = G->var[i]->start[G->element[i]] + amplitude * sin(phase) +
                                 (outlier ? 3.0 : 0.0);
        }
}

/* `steps` steps: every Real input set from the precomputed signals, DoStep, every output read. */
static void timed_steps(Instance c, long steps) {
    Group *R = &groups[INPUTS][0];
    void *set = calls[1][0];
    size_t m = (size_t)R->nvr;
    for (long s = 0; s < steps; s++) {
        const double *values = signals + (timed_k % SIGNAL_PERIOD) * R->nvalues;
        if (m) {
            Status st = version == 2
                            ? (*(Call2 *)&set)(c, R->vrs, m, (void *)values)
                            : (*(Call3 *)&set)(c, R->vrs, m, (void *)values, (size_t)R->nvalues);
            check(st, CALLS[version - 2][1][0]);
        }
        if (version == 2) {
            check(F.step2(c, timed_t, step, 1), "fmi2DoStep");
        } else {
            bool event = false, terminate = false, early = false;
            double last = 0.0;
            check(F.step3(c, timed_t, step, true, &event, &terminate, &early, &last),
                  "fmi3DoStep");
        }
        exchange(c, OUTPUTS, 0, 0);
        timed_t += step;
        timed_k++;
    }
}

static double ns_per_step(Instance c, long steps) {
    double t0 = now();
    timed_steps(c, steps);
    return 1e9 * (now() - t0) / (double)(steps > 0 ? steps : 1);
}

static int time_steps(long steps, int batches, double amplitude, int outliers) {
    form_signals(amplitude, outliers);
    Instance c = start();
    ns_per_step(c, steps > 0 ? steps : 1); /* warm-up */
    if (batches == 0) {
        char line[64];
        while (fgets(line, sizeof line, stdin)) {
            long n = atol(line);
            if (n < 1) { fprintf(stderr, "driver: bad step count '%s'\n", line); return 2; }
            printf("%.3f\n", ns_per_step(c, n));
            fflush(stdout);
        }
    } else {
        double *samples = calloc((size_t)batches, sizeof *samples);
        for (int b = 0; b < batches; b++) samples[b] = ns_per_step(c, steps);
        qsort(samples, (size_t)batches, sizeof *samples, by_value);
        printf("%s fmi%d: %.2f ns per step (median of %d batches of %ld steps)\n", label,
               version, samples[batches / 2], batches, steps);
    }
    stop(c);
    return 0;
}

int main(int argc, char **argv) {
    if (argc >= 6 && !strcmp(argv[4], "--time")) {
        int batches = atoi(argv[5]), outliers = 0;
        double amplitude = 0.1, forced_step = 0.0;
        for (int i = 6; i < argc; i++) {
            if (!strcmp(argv[i], "--outliers")) outliers = 1;
            else if (!strcmp(argv[i], "--amplitude") && i + 1 < argc) amplitude = atof(argv[++i]);
            else if (!strcmp(argv[i], "--step") && i + 1 < argc) forced_step = atof(argv[++i]);
            else { fprintf(stderr, "driver: unknown argument '%s'\n", argv[i]); return 2; }
        }
        if (batches < 0) { fprintf(stderr, "driver: BATCHES must be >= 0\n"); return 2; }
        read_manifest(argv[1]);
        if (forced_step > 0) step = forced_step;
        load();
        build_groups();
        return time_steps(atol(argv[2]), batches, amplitude, outliers);
    }
    if (argc != 4) {
        fprintf(stderr, "usage: driver MANIFEST STEPS REPEATS [--time BATCHES [--amplitude A] "
                        "[--outliers] [--step H]]\n");
        return 2;
    }
    read_manifest(argv[1]);
    long steps = atol(argv[2]);
    int repeats = atoi(argv[3]);
    if (repeats < 1) repeats = 1;
    load();
    build_groups();

    /* 1. What one instance costs, after a warm-up instance. */
    stop(start());
    double *times = calloc((size_t)repeats, sizeof *times);
    long long bytes = 0;
    for (int r = 0; r < repeats; r++) {
        live = 0;
        measuring = 1;
        double t0 = now();
        Instance c = start();
        times[r] = now() - t0;
        measuring = 0;
        if (live > bytes) bytes = live;
        stop(c);
    }
    qsort(times, (size_t)repeats, sizeof *times, by_value);

    /* 2. The step phase. */
    Instance c = start();
    double t = 0.0;
    counting = 1;
    for (long n = 0; n < steps; n++) {
        exchange(c, INPUTS, 1, n);
        if (version == 2) {
            check(F.step2(c, t, step, 1), "fmi2DoStep");
        } else {
            bool event = false, terminate = false, early = false;
            double last = 0.0;
            check(F.step3(c, t, step, true, &event, &terminate, &early, &last), "fmi3DoStep");
        }
        t += step;
        exchange(c, OUTPUTS, 0, n);
    }
    counting = 0;
    stop(c);

    long allocations = n_malloc + n_calloc + n_realloc + n_aligned;
    printf("%-32s fmi%d: %ld steps, %ld allocations (%ld malloc, %ld calloc, %ld realloc, "
           "%ld aligned), %ld frees; instance %lld B, instantiate+initialise %.3f ms\n",
           label, version, steps, allocations, n_malloc, n_calloc, n_realloc, n_aligned, n_free,
           bytes, 1e3 * times[repeats / 2]);
    return allocations || n_free ? 1 : 0;
}
