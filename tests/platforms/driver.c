/*
 * A minimal FMI Co-Simulation driver for FMI 2.0 and, built with -DFMI3, FMI 3.0; one source for
 * every platform (built with gcc, x86_64-w64-mingw32-gcc and aarch64-linux-gnu-gcc): it loads an
 * FMU binary, resolves the 34 fmi2 functions (FMI 3.0: the 75 fmi3 functions of
 * fmi3FunctionTypes.h; a missing one is a failure), instantiates Co-Simulation with a given
 * resource location (FMI 2.0: a URI; FMI 3.0: a path), applies start values, initialises, steps
 * with inputs from a CSV (held between its rows) and writes every output (element) after each
 * step as the hexadecimal bits of the IEEE double (exact, for bit comparison between platforms).
 * The version-specific calls are the few functions under `#ifdef FMI3` below; the scenario, CSV
 * and stepping code is shared.
 *
 *   driver BINARY RESOURCE_URI SCENARIO OUT_CSV
 *   driver3 BINARY RESOURCE_PATH SCENARIO OUT_CSV     (built with -DFMI3)
 *
 * FMI 3.0: RESOURCE_PATH is passed to the FMU in UTF-8 (on Windows, converted from the wide
 * command line), and fmi3DoStep's eventHandlingNeeded, terminateSimulation, earlyReturn and
 * lastSuccessfulTime are checked.
 *
 * SCENARIO is a text file, one directive a line (`#` comments; written by scenario.py):
 *   guid {…}                      the model description's GUID (FMI 3.0: `token {…}`)
 *   identifier NAME               the instance name
 *   experiment START STOP STEP    (or: opt FILE, a cross-check `<Model>_ref.opt`)
 *   inputs FILE                   a cross-check `<Model>_in.csv`: `time` then input names
 *   start r|i|b VR VALUE          a start value set before initialisation
 *   input r|i|b VR NAME           an input, fed from the CSV column NAME
 *   output r|i|b VR NAME          an output, written after every step
 * FILE paths are relative to the scenario's folder. FMI 3.0: an array is one value reference
 * listed once per element, in row-major order, consecutively: those lines make one fmi3Set/fmi3Get
 * call with nValues = their number.
 *
 * Exit status: 0 all steps OK; 2 usage, file or symbol problem; 3 instantiation failed;
 * 4 a call returned Error; 5 a call returned Fatal; 6 any other non-OK status (or, FMI 3.0, an
 * unexpected fmi3DoStep flag).
 * Log messages of the FMU go to stderr, as `[status] category: message`.
 */
#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#include <shellapi.h>
#define LOAD(path) ((void *)LoadLibraryA(path))
#define SYMBOL(lib, name) ((void *)GetProcAddress((HMODULE)(lib), name))
#else
#include <dlfcn.h>
#define LOAD(path) dlopen(path, RTLD_NOW | RTLD_LOCAL)
#define SYMBOL(lib, name) dlsym(lib, name)
#endif

typedef void *Instance;
typedef int Status; /* 0 OK, 1 Warning, 2 Discard, 3 Error, 4 Fatal, 5 Pending (FMI 2.0) */
typedef Status (*PlainFn)(Instance);
typedef void (*FreeFn)(Instance);

#ifdef FMI3
#define DRIVER "driver3"
#define VERSION "fmi3"
#define ID_WORD "token"
#define INSTANTIATE_NAME "fmi3InstantiateCoSimulation"
typedef void (*LogFn)(void *, Status, const char *, const char *);
typedef Instance (*InstantiateFn)(const char *, const char *, const char *, bool, bool, bool,
                                  bool, const uint32_t *, size_t, void *, LogFn, void *);
typedef Status (*EnterInitFn)(Instance, bool, double, double, bool, double);
typedef Status (*SetF64Fn)(Instance, const uint32_t *, size_t, const double *, size_t);
typedef Status (*GetF64Fn)(Instance, const uint32_t *, size_t, double *, size_t);
typedef Status (*SetI32Fn)(Instance, const uint32_t *, size_t, const int32_t *, size_t);
typedef Status (*GetI32Fn)(Instance, const uint32_t *, size_t, int32_t *, size_t);
typedef Status (*SetBoolFn)(Instance, const uint32_t *, size_t, const bool *, size_t);
typedef Status (*GetBoolFn)(Instance, const uint32_t *, size_t, bool *, size_t);
typedef Status (*DoStepFn)(Instance, double, double, bool, bool *, bool *, bool *, double *);

static const char *const NAMES[] = {
    "fmi3GetVersion", "fmi3InstantiateCoSimulation", "fmi3FreeInstance",
    "fmi3EnterInitializationMode", "fmi3ExitInitializationMode", "fmi3Terminate",
    "fmi3SetFloat64", "fmi3GetFloat64", "fmi3SetInt32", "fmi3GetInt32", "fmi3SetBoolean",
    "fmi3GetBoolean", "fmi3DoStep",
    /* The rest of the API: resolved only to check that it is exported. */
    "fmi3ActivateModelPartition", "fmi3CompletedIntegratorStep", "fmi3DeserializeFMUState",
    "fmi3EnterConfigurationMode", "fmi3EnterContinuousTimeMode", "fmi3EnterEventMode",
    "fmi3EnterStepMode", "fmi3EvaluateDiscreteStates", "fmi3ExitConfigurationMode",
    "fmi3FreeFMUState", "fmi3GetAdjointDerivative", "fmi3GetBinary", "fmi3GetClock",
    "fmi3GetContinuousStateDerivatives", "fmi3GetContinuousStates",
    "fmi3GetDirectionalDerivative", "fmi3GetEventIndicators", "fmi3GetFMUState",
    "fmi3GetFloat32", "fmi3GetInt16", "fmi3GetInt64", "fmi3GetInt8", "fmi3GetIntervalDecimal",
    "fmi3GetIntervalFraction", "fmi3GetNominalsOfContinuousStates",
    "fmi3GetNumberOfContinuousStates", "fmi3GetNumberOfEventIndicators",
    "fmi3GetNumberOfVariableDependencies", "fmi3GetOutputDerivatives", "fmi3GetShiftDecimal",
    "fmi3GetShiftFraction", "fmi3GetString", "fmi3GetUInt16", "fmi3GetUInt32", "fmi3GetUInt64",
    "fmi3GetUInt8", "fmi3GetVariableDependencies", "fmi3InstantiateModelExchange",
    "fmi3InstantiateScheduledExecution", "fmi3Reset", "fmi3SerializeFMUState",
    "fmi3SerializedFMUStateSize", "fmi3SetBinary", "fmi3SetClock", "fmi3SetContinuousStates",
    "fmi3SetDebugLogging", "fmi3SetFMUState", "fmi3SetFloat32", "fmi3SetInt16", "fmi3SetInt64",
    "fmi3SetInt8", "fmi3SetIntervalDecimal", "fmi3SetIntervalFraction", "fmi3SetShiftDecimal",
    "fmi3SetShiftFraction", "fmi3SetString", "fmi3SetTime", "fmi3SetUInt16", "fmi3SetUInt32",
    "fmi3SetUInt64", "fmi3SetUInt8", "fmi3UpdateDiscreteStates"};
enum { GET_VERSION, INSTANTIATE, FREE_INSTANCE, ENTER_INIT, EXIT_INIT, TERMINATE, SET_F64,
       GET_F64, SET_I32, GET_I32, SET_BOOL, GET_BOOL, DO_STEP };
#else
#define DRIVER "driver"
#define VERSION "fmi2"
#define ID_WORD "guid"
#define INSTANTIATE_NAME "fmi2Instantiate"
/* The FMI 2.0 C types this driver uses (platform "default"). */
typedef struct {
    void (*logger)(void *, const char *, Status, const char *, const char *, ...);
    void *(*allocate)(size_t, size_t);
    void (*free)(void *);
    void (*step_finished)(void *, Status);
    void *environment;
} Callbacks;
typedef Instance (*InstantiateFn)(const char *, int, const char *, const char *, const Callbacks *,
                                  int, int);
typedef Status (*SetupFn)(Instance, int, double, double, int, double);
typedef Status (*RealFn)(Instance, const unsigned *, size_t, double *);
typedef Status (*IntFn)(Instance, const unsigned *, size_t, int *);
typedef Status (*DoStepFn)(Instance, double, double, int);

static const char *const NAMES[] = {
    "fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging", "fmi2Instantiate",
    "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset", "fmi2GetReal",
    "fmi2GetInteger", "fmi2GetBoolean", "fmi2GetString", "fmi2SetReal", "fmi2SetInteger",
    "fmi2SetBoolean", "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate",
    "fmi2FreeFMUstate", "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate",
    "fmi2DeSerializeFMUstate", "fmi2GetDirectionalDerivative", "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives", "fmi2DoStep", "fmi2CancelStep", "fmi2GetStatus",
    "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus",
    "fmi2GetStringStatus"};
enum { GET_TYPES_PLATFORM, GET_VERSION, SET_DEBUG_LOGGING, INSTANTIATE, FREE_INSTANCE,
       SETUP_EXPERIMENT, ENTER_INIT, EXIT_INIT, TERMINATE, RESET, GET_REAL, GET_INTEGER,
       GET_BOOLEAN, GET_STRING, SET_REAL, SET_INTEGER, SET_BOOLEAN };
enum { DO_STEP = 27 };
#endif
enum { N_FUNCTIONS = sizeof NAMES / sizeof NAMES[0] };

#define MAX_VARS 1024
#define MAX_LINE 65536

typedef struct {
    char type; /* 'r', 'i' or 'b' */
    unsigned vr;
    char name[256];
    double value; /* start value, or the current input */
    int column;   /* input: CSV column index */
} Var;

static Var starts[MAX_VARS], inputs[MAX_VARS], outputs[MAX_VARS];
static int n_starts, n_inputs, n_outputs;
static char id[256], identifier[256] = "instance", inputs_file[1024];
static double t_start = 0.0, t_stop = 1.0, t_step = 0.01;
static double *csv; /* rows of (time, columns...) */
static int csv_rows, csv_cols;
static void *fn[N_FUNCTIONS];
/* One run of values of one value reference (FMI 3.0: an array; FMI 2.0: one element at a time). */
static double values_r[MAX_VARS];
static int32_t values_i[MAX_VARS];
static bool values_b[MAX_VARS];

static void fail(int code, const char *what, const char *detail) {
    fprintf(stderr, DRIVER ": %s%s%s\n", what, detail ? ": " : "", detail ? detail : "");
    exit(code);
}

/* Exit code for a non-OK status of `call`. */
static void check(Status status, const char *call, double time) {
    if (status == 0) return;
    fprintf(stderr, DRIVER ": %s returned status %d at t = %.17g\n", call, status, time);
    printf("# %s status %d at t = %.17g\n", call, status, time);
    exit(status == 3 ? 4 : status == 4 ? 5 : 6);
}

#ifdef FMI3
/* Argument `index` in UTF-8, as FMI 3.0 strings are: on Windows argv is in the ANSI code page,
 * so the resource path (which may hold any letter) is taken from the wide command line. */
static const char *utf8_arg(char **argv, int index) {
#ifdef _WIN32
    int n = 0;
    LPWSTR *wide = CommandLineToArgvW(GetCommandLineW(), &n);
    if (!wide || index >= n) return argv[index];
    int len = WideCharToMultiByte(CP_UTF8, 0, wide[index], -1, NULL, 0, NULL, NULL);
    char *text = malloc((size_t)len);
    if (!text) return argv[index];
    WideCharToMultiByte(CP_UTF8, 0, wide[index], -1, text, len, NULL, NULL);
    LocalFree(wide);
    return text;
#else
    return argv[index];
#endif
}

static void log_message(void *env, Status status, const char *category, const char *message) {
    (void)env;
    fprintf(stderr, "[%d] %s: %s\n", status, category ? category : "", message ? message : "");
}

static void check_version(const char *binary) {
    if (strcmp(((const char *(*)(void))fn[GET_VERSION])(), "3.0"))
        fail(2, "unexpected version", binary);
}

static Instance instantiate(char **argv) {
    return ((InstantiateFn)fn[INSTANTIATE])(identifier, id, utf8_arg(argv, 2), false, false,
                                            false, false, NULL, 0, NULL, log_message, NULL);
}

static void enter_init(Instance c) {
    check(((EnterInitFn)fn[ENTER_INIT])(c, false, 0.0, t_start, true, t_stop),
          "fmi3EnterInitializationMode", t_start);
}

/* Sets the m values of value reference vr from values_*. */
static Status set_run(Instance c, char type, unsigned vr, int m) {
    const uint32_t ref = vr;
    if (type == 'r') return ((SetF64Fn)fn[SET_F64])(c, &ref, 1, values_r, (size_t)m);
    if (type == 'i') return ((SetI32Fn)fn[SET_I32])(c, &ref, 1, values_i, (size_t)m);
    return ((SetBoolFn)fn[SET_BOOL])(c, &ref, 1, values_b, (size_t)m);
}

/* Reads the m values of value reference vr into values_*. */
static void get_run(Instance c, char type, unsigned vr, int m, double t) {
    const uint32_t ref = vr;
    if (type == 'r')
        check(((GetF64Fn)fn[GET_F64])(c, &ref, 1, values_r, (size_t)m), "fmi3GetFloat64", t);
    else if (type == 'i')
        check(((GetI32Fn)fn[GET_I32])(c, &ref, 1, values_i, (size_t)m), "fmi3GetInt32", t);
    else
        check(((GetBoolFn)fn[GET_BOOL])(c, &ref, 1, values_b, (size_t)m), "fmi3GetBoolean", t);
}

static Status do_step(Instance c, double t, double h) {
    bool event = true, terminate = true, early = true;
    double last = -1.0;
    Status s = ((DoStepFn)fn[DO_STEP])(c, t, h, true, &event, &terminate, &early, &last);
    if (s == 0 && (event || terminate || early || last != t + h)) {
        fprintf(stderr, "driver3: fmi3DoStep at t = %.17g gave eventHandlingNeeded %d, "
                        "terminateSimulation %d, earlyReturn %d, lastSuccessfulTime %.17g\n",
                t, event, terminate, early, last);
        exit(6);
    }
    return s;
}
#else
static void logger(void *env, const char *instance, Status status, const char *category,
                   const char *message, ...) {
    va_list args;
    (void)env;
    fprintf(stderr, "[%d] %s %s: ", status, instance ? instance : "?",
            category ? category : "");
    va_start(args, message);
    vfprintf(stderr, message ? message : "", args);
    va_end(args);
    fputc('\n', stderr);
}

static void check_version(const char *binary) {
    if (strcmp(((const char *(*)(void))fn[GET_TYPES_PLATFORM])(), "default") ||
        strcmp(((const char *(*)(void))fn[GET_VERSION])(), "2.0"))
        fail(2, "unexpected types platform or version", binary);
}

static Instance instantiate(char **argv) {
    static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    return ((InstantiateFn)fn[INSTANTIATE])(identifier, 1 /* fmi2CoSimulation */, id, argv[2],
                                            &callbacks, 0, 0);
}

static void enter_init(Instance c) {
    check(((SetupFn)fn[SETUP_EXPERIMENT])(c, 0, 0.0, t_start, 1, t_stop), "fmi2SetupExperiment",
          t_start);
    check(((PlainFn)fn[ENTER_INIT])(c), "fmi2EnterInitializationMode", t_start);
}

/* Sets the m values of value reference vr from values_*, one fmi2Set call each. */
static Status set_run(Instance c, char type, unsigned vr, int m) {
    for (int e = 0; e < m; e++) {
        Status s;
        if (type == 'r') {
            s = ((RealFn)fn[SET_REAL])(c, &vr, 1, &values_r[e]);
        } else {
            int v = type == 'i' ? (int)values_i[e] : (int)values_b[e];
            s = ((IntFn)fn[type == 'i' ? SET_INTEGER : SET_BOOLEAN])(c, &vr, 1, &v);
        }
        if (s != 0) return s;
    }
    return 0;
}

/* Reads the m values of value reference vr into values_*, one fmi2Get call each. */
static void get_run(Instance c, char type, unsigned vr, int m, double t) {
    for (int e = 0; e < m; e++) {
        int k;
        if (type == 'r') {
            check(((RealFn)fn[GET_REAL])(c, &vr, 1, &values_r[e]), "fmi2GetReal", t);
            continue;
        }
        check(((IntFn)fn[type == 'i' ? GET_INTEGER : GET_BOOLEAN])(c, &vr, 1, &k),
              "fmi2GetInteger/Boolean", t);
        values_i[e] = k;
        values_b[e] = k != 0;
    }
}

static Status do_step(Instance c, double t, double h) {
    return ((DoStepFn)fn[DO_STEP])(c, t, h, 1);
}
#endif

static void join(char *out, size_t size, const char *base, const char *file) {
    const char *slash = strrchr(base, '/');
    const char *back = strrchr(base, '\\');
    if (back && (!slash || back > slash)) slash = back;
    if (slash)
        snprintf(out, size, "%.*s/%s", (int)(slash - base), base, file);
    else
        snprintf(out, size, "%s", file);
}

static void read_opt(const char *path) {
    char line[1024], key[64];
    double v;
    FILE *f = fopen(path, "r");
    if (!f) fail(2, "cannot open", path);
    while (fgets(line, sizeof line, f)) {
        if (sscanf(line, " %63[^, ] , %lf", key, &v) != 2) continue;
        if (!strcmp(key, "StartTime")) t_start = v;
        else if (!strcmp(key, "StopTime")) t_stop = v;
        else if (!strcmp(key, "StepSize")) t_step = v;
    }
    fclose(f);
}

static void read_scenario(const char *path) {
    static char line[MAX_LINE];
    char word[64], type[8], rest[1024];
    FILE *f = fopen(path, "r");
    if (!f) fail(2, "cannot open", path);
    while (fgets(line, sizeof line, f)) {
        char *hash = strchr(line, '#');
        if (hash) *hash = 0;
        if (sscanf(line, "%63s", word) != 1) continue;
        if (!strcmp(word, ID_WORD)) {
            sscanf(line, "%*s %255s", id);
        } else if (!strcmp(word, "identifier")) {
            sscanf(line, "%*s %255s", identifier);
        } else if (!strcmp(word, "experiment")) {
            if (sscanf(line, "%*s %lf %lf %lf", &t_start, &t_stop, &t_step) != 3)
                fail(2, "bad experiment line", line);
        } else if (!strcmp(word, "opt")) {
            sscanf(line, "%*s %1023s", rest);
            char full[2048];
            join(full, sizeof full, path, rest);
            read_opt(full);
        } else if (!strcmp(word, "inputs")) {
            sscanf(line, "%*s %1023s", rest);
            join(inputs_file, sizeof inputs_file, path, rest);
        } else if (!strcmp(word, "start") || !strcmp(word, "input") ||
                   !strcmp(word, "output")) {
            Var v = {0};
            int *n = word[0] == 's' ? &n_starts : word[0] == 'i' ? &n_inputs : &n_outputs;
            Var *list = word[0] == 's' ? starts : word[0] == 'i' ? inputs : outputs;
            if (sscanf(line, "%*s %7s %u %255s", type, &v.vr, v.name) != 3 ||
                !strchr("rib", type[0]))
                fail(2, "bad variable line", line);
            v.type = type[0];
            if (word[0] == 's') v.value = strtod(v.name, NULL);
            if (*n >= MAX_VARS) fail(2, "too many variables", path);
            list[(*n)++] = v;
        } else {
            fail(2, "unknown scenario directive", word);
        }
    }
    fclose(f);
    if (!id[0]) fail(2, "the scenario has no " ID_WORD, path);
    if (!(t_step > 0) || t_stop < t_start) fail(2, "bad experiment", path);
}

/* Reads the inputs CSV and maps each input to its column. */
static void read_inputs(void) {
    static char line[MAX_LINE];
    static char names[MAX_VARS][256];
    int i, c;
    if (!n_inputs) return;
    if (!inputs_file[0]) fail(2, "inputs declared but no inputs file", NULL);
    FILE *f = fopen(inputs_file, "r");
    if (!f || !fgets(line, sizeof line, f)) fail(2, "cannot read", inputs_file);
    line[strcspn(line, "\r\n")] = 0;
    csv_cols = 0;
    /* Header cells, optionally in double quotes (array names such as "A[1,2]" have commas). */
    for (char *p = line; *p && csv_cols < MAX_VARS;) {
        size_t len = 0;
        char *cell = names[csv_cols];
        while (*p == ' ') p++;
        if (*p == '"') {
            for (p++; *p && *p != '"'; p++)
                if (len + 1 < sizeof names[0]) cell[len++] = *p;
            if (*p == '"') p++;
        } else {
            for (; *p && *p != ','; p++)
                if (len + 1 < sizeof names[0]) cell[len++] = *p;
        }
        while (len && cell[len - 1] == ' ') len--;
        cell[len] = 0;
        csv_cols++;
        while (*p == ' ') p++;
        if (*p == ',') p++;
    }
    if (!csv_cols || strcmp(names[0], "time")) fail(2, "the first column must be time", inputs_file);
    for (i = 0; i < n_inputs; i++) {
        inputs[i].column = -1;
        for (c = 1; c < csv_cols; c++)
            if (!strcmp(names[c], inputs[i].name)) inputs[i].column = c;
        if (inputs[i].column < 0) fail(2, "no CSV column for input", inputs[i].name);
    }
    int capacity = 1024;
    csv = malloc(sizeof(double) * capacity * csv_cols);
    while (fgets(line, sizeof line, f)) {
        if (line[strspn(line, " \r\n")] == 0) continue;
        if (csv_rows == capacity) {
            capacity *= 2;
            csv = realloc(csv, sizeof(double) * capacity * csv_cols);
        }
        char *p = line;
        for (c = 0; c < csv_cols; c++) {
            char *end;
            csv[csv_rows * csv_cols + c] = strtod(p, &end);
            if (end == p) fail(2, "bad number in", inputs_file);
            p = end;
            while (*p == ' ' || *p == ',') p++;
        }
        csv_rows++;
    }
    fclose(f);
}

/* Input values at time t: the last row with time <= t (sample and hold). */
static void inputs_at(double t) {
    int row = 0, i;
    while (row + 1 < csv_rows && csv[(row + 1) * csv_cols] <= t + 1e-9 * t_step) row++;
    for (i = 0; i < n_inputs; i++) inputs[i].value = csv[row * csv_cols + inputs[i].column];
}

/* The end of the run of `vars` from `i` with the same value reference (one array). */
static int run_end(const Var *vars, int n, int i) {
    int j = i + 1;
    while (j < n && vars[j].vr == vars[i].vr) j++;
    return j;
}

static void set_vars(Instance c, const Var *vars, int n, const char *what, double t) {
    for (int i = 0; i < n;) {
        int j = run_end(vars, n, i), m = j - i;
        for (int e = 0; e < m; e++) {
            values_r[e] = vars[i + e].value;
            values_i[e] = (int32_t)vars[i + e].value;
            values_b[e] = vars[i + e].value != 0.0;
        }
        check(set_run(c, vars[i].type, vars[i].vr, m), what, t);
        i = j;
    }
}

static void write_outputs(FILE *out, Instance c, double t) {
    uint64_t bits;
    memcpy(&bits, &t, sizeof bits);
    fprintf(out, "%016llx", (unsigned long long)bits);
    for (int i = 0; i < n_outputs;) {
        int j = run_end(outputs, n_outputs, i), m = j - i;
        get_run(c, outputs[i].type, outputs[i].vr, m, t);
        for (int e = 0; e < m; e++) {
            if (outputs[i].type == 'r') {
                memcpy(&bits, &values_r[e], sizeof bits);
                fprintf(out, ",%016llx", (unsigned long long)bits);
            } else {
                fprintf(out, ",%d", outputs[i].type == 'i' ? (int)values_i[e] : values_b[e] ? 1 : 0);
            }
        }
        i = j;
    }
    fputc('\n', out);
}

int main(int argc, char **argv) {
    int i;
    if (argc != 5) {
        fprintf(stderr, "usage: " DRIVER " BINARY RESOURCE_LOCATION SCENARIO OUT_CSV\n");
        return 2;
    }
    read_scenario(argv[3]);
    read_inputs();

    void *lib = LOAD(argv[1]);
    if (!lib) {
#ifdef _WIN32
        fprintf(stderr, DRIVER ": LoadLibrary error %lu\n", (unsigned long)GetLastError());
#else
        fprintf(stderr, DRIVER ": %s\n", dlerror());
#endif
        fail(2, "cannot load", argv[1]);
    }
    int missing = 0;
    for (i = 0; i < N_FUNCTIONS; i++) {
        fn[i] = SYMBOL(lib, NAMES[i]);
        if (!fn[i]) {
            fprintf(stderr, DRIVER ": %s does not export %s\n", argv[1], NAMES[i]);
            missing++;
        }
    }
    if (missing) fail(2, "missing " VERSION " functions", argv[1]);
    check_version(argv[1]);

    Instance c = instantiate(argv);
    if (!c) fail(3, INSTANTIATE_NAME " failed for", argv[1]);

    FILE *out = fopen(argv[4], "w");
    if (!out) fail(2, "cannot write", argv[4]);
    fprintf(out, "time");
    for (i = 0; i < n_outputs; i++) fprintf(out, ",\"%s\"", outputs[i].name);
    fputc('\n', out);

    set_vars(c, starts, n_starts, VERSION "Set (start value)", t_start);
    enter_init(c);
    if (n_inputs) {
        inputs_at(t_start);
        set_vars(c, inputs, n_inputs, VERSION "Set (input)", t_start);
    }
    check(((PlainFn)fn[EXIT_INIT])(c), VERSION "ExitInitializationMode", t_start);
    write_outputs(out, c, t_start);

    /* Communication points t_start + k h, counted, so that no rounding accumulates. */
    long steps = (long)((t_stop - t_start) / t_step + 0.5);
    for (long k = 0; k < steps; k++) {
        double t = t_start + (double)k * t_step;
        double next = t_start + (double)(k + 1) * t_step;
        if (n_inputs) {
            inputs_at(t);
            set_vars(c, inputs, n_inputs, VERSION "Set (input)", t);
        }
        Status s = do_step(c, t, next - t);
        if (s != 0) {
            fflush(out);
            check(s, VERSION "DoStep", t);
        }
        write_outputs(out, c, next);
    }
    check(((PlainFn)fn[TERMINATE])(c), VERSION "Terminate", t_stop);
    ((FreeFn)fn[FREE_INSTANCE])(c);
    fclose(out);
    printf("%ld steps\n", steps);
    return 0;
}
