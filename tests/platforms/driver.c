/*
 * A minimal FMI 2.0 Co-Simulation driver, one source for every platform (built with gcc,
 * x86_64-w64-mingw32-gcc and aarch64-linux-gnu-gcc): it loads an FMU binary, resolves the 34
 * fmi2 functions (a missing one is a failure), instantiates with a given resource-location URI,
 * applies start values, initialises, steps with inputs from a CSV (held between its rows) and
 * writes every output after each step as the hexadecimal bits of the IEEE double (exact, for
 * bit comparison between platforms).
 *
 *   driver BINARY RESOURCE_URI SCENARIO OUT_CSV
 *
 * SCENARIO is a text file, one directive a line (`#` comments; written by scenario.py):
 *   guid {…}                      the model description's GUID
 *   identifier NAME               the instance name
 *   experiment START STOP STEP    (or: opt FILE, a cross-check `<Model>_ref.opt`)
 *   inputs FILE                   a cross-check `<Model>_in.csv`: `time` then input names
 *   start r|i|b VR VALUE          a start value set before initialisation
 *   input r|i|b VR NAME           an input, fed from the CSV column NAME
 *   output r|i|b VR NAME          an output, written after every step
 * FILE paths are relative to the scenario's folder.
 *
 * Exit status: 0 all steps OK; 2 usage, file or symbol problem; 3 instantiation failed;
 * 4 a call returned fmi2Error; 5 a call returned fmi2Fatal; 6 any other non-OK status.
 * Log messages of the FMU go to stderr, as `[status] category: message`.
 */
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define LOAD(path) ((void *)LoadLibraryA(path))
#define SYMBOL(lib, name) ((void *)GetProcAddress((HMODULE)(lib), name))
#else
#include <dlfcn.h>
#define LOAD(path) dlopen(path, RTLD_NOW | RTLD_LOCAL)
#define SYMBOL(lib, name) dlsym(lib, name)
#endif

/* The FMI 2.0 C types this driver uses (platform "default"). */
typedef void *Component;
typedef int Status; /* 0 OK, 1 Warning, 2 Discard, 3 Error, 4 Fatal, 5 Pending */
typedef struct {
    void (*logger)(void *, const char *, Status, const char *, const char *, ...);
    void *(*allocate)(size_t, size_t);
    void (*free)(void *);
    void (*step_finished)(void *, Status);
    void *environment;
} Callbacks;

typedef Component (*InstantiateFn)(const char *, int, const char *, const char *,
                                   const Callbacks *, int, int);
typedef Status (*SetupFn)(Component, int, double, double, int, double);
typedef Status (*PlainFn)(Component);
typedef void (*FreeFn)(Component);
typedef Status (*RealFn)(Component, const unsigned *, size_t, double *);
typedef Status (*IntFn)(Component, const unsigned *, size_t, int *);
typedef Status (*DoStepFn)(Component, double, double, int);

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
enum { N_FUNCTIONS = sizeof NAMES / sizeof NAMES[0] };
enum { GET_TYPES_PLATFORM, GET_VERSION, SET_DEBUG_LOGGING, INSTANTIATE, FREE_INSTANCE,
       SETUP_EXPERIMENT, ENTER_INIT, EXIT_INIT, TERMINATE, RESET, GET_REAL, GET_INTEGER,
       GET_BOOLEAN, GET_STRING, SET_REAL, SET_INTEGER, SET_BOOLEAN };
enum { DO_STEP = 27 };

#define MAX_VARS 512
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
static char guid[256], identifier[256] = "instance", inputs_file[1024];
static double t_start = 0.0, t_stop = 1.0, t_step = 0.01;
static double *csv; /* rows of (time, columns...) */
static int csv_rows, csv_cols;
static void *fn[N_FUNCTIONS];

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

static void fail(int code, const char *what, const char *detail) {
    fprintf(stderr, "driver: %s%s%s\n", what, detail ? ": " : "", detail ? detail : "");
    exit(code);
}

/* Exit code for a non-OK status of `call`. */
static void check(Status status, const char *call, double time) {
    if (status == 0) return;
    fprintf(stderr, "driver: %s returned status %d at t = %.17g\n", call, status, time);
    printf("# %s status %d at t = %.17g\n", call, status, time);
    exit(status == 3 ? 4 : status == 4 ? 5 : 6);
}

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
        if (!strcmp(word, "guid")) {
            sscanf(line, "%*s %255s", guid);
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
    if (!guid[0]) fail(2, "the scenario has no guid", path);
    if (!(t_step > 0) || t_stop < t_start) fail(2, "bad experiment", path);
}

/* Reads the inputs CSV and maps each input to its column. */
static void read_inputs(void) {
    static char line[MAX_LINE];
    int i, c;
    if (!n_inputs) return;
    if (!inputs_file[0]) fail(2, "inputs declared but no inputs file", NULL);
    FILE *f = fopen(inputs_file, "r");
    if (!f || !fgets(line, sizeof line, f)) fail(2, "cannot read", inputs_file);
    line[strcspn(line, "\r\n")] = 0;
    char *names[MAX_VARS];
    csv_cols = 0;
    /* Header cells, optionally in double quotes (array names such as "A[1,2]" have commas). */
    for (char *p = line; *p && csv_cols < MAX_VARS;) {
        char cell[256];
        size_t len = 0;
        while (*p == ' ') p++;
        if (*p == '"') {
            for (p++; *p && *p != '"'; p++)
                if (len + 1 < sizeof cell) cell[len++] = *p;
            if (*p == '"') p++;
        } else {
            for (; *p && *p != ','; p++)
                if (len + 1 < sizeof cell) cell[len++] = *p;
        }
        while (len && cell[len - 1] == ' ') len--;
        cell[len] = 0;
        names[csv_cols] = malloc(len + 1);
        strcpy(names[csv_cols++], cell);
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
    for (c = 1; c < csv_cols; c++) free(names[c]);
    free(names[0]);
}

/* Input values at time t: the last row with time <= t (sample and hold). */
static void inputs_at(double t) {
    int row = 0, i;
    while (row + 1 < csv_rows && csv[(row + 1) * csv_cols] <= t + 1e-9 * t_step) row++;
    for (i = 0; i < n_inputs; i++) inputs[i].value = csv[row * csv_cols + inputs[i].column];
}

static void set_vars(Component c, Var *vars, int n, const char *what, double t) {
    int i;
    for (i = 0; i < n; i++) {
        Status s;
        if (vars[i].type == 'r') {
            s = ((RealFn)fn[SET_REAL])(c, &vars[i].vr, 1, &vars[i].value);
        } else {
            int v = (int)vars[i].value;
            s = ((IntFn)fn[vars[i].type == 'i' ? SET_INTEGER : SET_BOOLEAN])(c, &vars[i].vr, 1, &v);
        }
        check(s, what, t);
    }
}

static void write_outputs(FILE *out, Component c, double t) {
    int i;
    uint64_t bits;
    memcpy(&bits, &t, sizeof bits);
    fprintf(out, "%016llx", (unsigned long long)bits);
    for (i = 0; i < n_outputs; i++) {
        double r;
        int k;
        if (outputs[i].type == 'r') {
            check(((RealFn)fn[GET_REAL])(c, &outputs[i].vr, 1, &r), "fmi2GetReal", t);
            memcpy(&bits, &r, sizeof bits);
            fprintf(out, ",%016llx", (unsigned long long)bits);
        } else {
            check(((IntFn)fn[outputs[i].type == 'i' ? GET_INTEGER : GET_BOOLEAN])(
                      c, &outputs[i].vr, 1, &k),
                  "fmi2GetInteger/Boolean", t);
            fprintf(out, ",%d", k);
        }
    }
    fputc('\n', out);
}

int main(int argc, char **argv) {
    int i;
    if (argc != 5) {
        fprintf(stderr, "usage: driver BINARY RESOURCE_URI SCENARIO OUT_CSV\n");
        return 2;
    }
    read_scenario(argv[3]);
    read_inputs();

    void *lib = LOAD(argv[1]);
    if (!lib) {
#ifdef _WIN32
        fprintf(stderr, "driver: LoadLibrary error %lu\n", (unsigned long)GetLastError());
#else
        fprintf(stderr, "driver: %s\n", dlerror());
#endif
        fail(2, "cannot load", argv[1]);
    }
    int missing = 0;
    for (i = 0; i < N_FUNCTIONS; i++) {
        fn[i] = SYMBOL(lib, NAMES[i]);
        if (!fn[i]) {
            fprintf(stderr, "driver: %s does not export %s\n", argv[1], NAMES[i]);
            missing++;
        }
    }
    if (missing) fail(2, "missing fmi2 functions", argv[1]);
    if (strcmp(((const char *(*)(void))fn[GET_TYPES_PLATFORM])(), "default") ||
        strcmp(((const char *(*)(void))fn[GET_VERSION])(), "2.0"))
        fail(2, "unexpected types platform or version", argv[1]);

    Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    Component c = ((InstantiateFn)fn[INSTANTIATE])(identifier, 1 /* fmi2CoSimulation */, guid,
                                                   argv[2], &callbacks, 0, 0);
    if (!c) fail(3, "fmi2Instantiate failed for", argv[1]);

    FILE *out = fopen(argv[4], "w");
    if (!out) fail(2, "cannot write", argv[4]);
    fprintf(out, "time");
    for (i = 0; i < n_outputs; i++) fprintf(out, ",\"%s\"", outputs[i].name);
    fputc('\n', out);

    set_vars(c, starts, n_starts, "fmi2Set (start value)", t_start);
    check(((SetupFn)fn[SETUP_EXPERIMENT])(c, 0, 0.0, t_start, 1, t_stop),
          "fmi2SetupExperiment", t_start);
    check(((PlainFn)fn[ENTER_INIT])(c), "fmi2EnterInitializationMode", t_start);
    if (n_inputs) {
        inputs_at(t_start);
        set_vars(c, inputs, n_inputs, "fmi2Set (input)", t_start);
    }
    check(((PlainFn)fn[EXIT_INIT])(c), "fmi2ExitInitializationMode", t_start);
    write_outputs(out, c, t_start);

    /* Communication points t_start + k h, counted, so that no rounding accumulates. */
    long steps = (long)((t_stop - t_start) / t_step + 0.5);
    for (long k = 0; k < steps; k++) {
        double t = t_start + (double)k * t_step;
        double next = t_start + (double)(k + 1) * t_step;
        if (n_inputs) {
            inputs_at(t);
            set_vars(c, inputs, n_inputs, "fmi2Set (input)", t);
        }
        Status s = ((DoStepFn)fn[DO_STEP])(c, t, next - t, 1);
        if (s != 0) {
            fflush(out);
            check(s, "fmi2DoStep", t);
        }
        write_outputs(out, c, next);
    }
    check(((PlainFn)fn[TERMINATE])(c), "fmi2Terminate", t_stop);
    ((FreeFn)fn[FREE_INSTANCE])(c);
    fclose(out);
    printf("%ld steps\n", steps);
    return 0;
}
