/*
 * Minimal FMI 2.0 co-simulation host in plain C (no Python anywhere).
 *
 * usage: host FMU_DIR MODEL_IDENTIFIER GUID STEP_SIZE N_STEPS INPUT_FILE IN_VRS OUT_VRS [PARAMS]
 *   FMU_DIR     unpacked FMU
 *   INPUT_FILE  N_STEPS rows of len(IN_VRS) numbers (input values before each step)
 *   IN_VRS      comma-separated Real value references of the inputs ("-" for none)
 *   OUT_VRS     comma-separated Real value references of the outputs
 *   PARAMS      optional "vr=value,vr=value" Real start values set before initialisation
 * Prints one line per step: the outputs after the step separated by spaces, each as its
 * bits, 0x and 16 hex digits (exact, whatever the C library's printf does with %.17g).
 * Exit status 0 on success, 1 on any FMI status above fmi2Warning.
 * Built for Windows (mingw-w64) it loads binaries/win64/<id>.dll; FMU_DIR is then a
 * Windows path such as Z:/tmp/fmu.
 */
#ifdef _WIN32
#include <windows.h>
#define LIB_OPEN(path) ((void*)LoadLibraryA(path))
#define LIB_SYM(lib, name) ((void*)GetProcAddress((HMODULE)(lib), name))
#define LIB_ERROR() "LoadLibrary failed"
#define BINARY "%s/binaries/win64/%s.dll"
#define URI "file:///%s/resources"
#else
#include <dlfcn.h>
#define LIB_OPEN(path) dlopen(path, RTLD_NOW | RTLD_LOCAL)
#define LIB_SYM(lib, name) dlsym(lib, name)
#define LIB_ERROR() dlerror()
#define BINARY "%s/binaries/linux64/%s.so"
#define URI "file://%s/resources"
#endif
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void* fmi2Component;
typedef unsigned int fmi2ValueReference;
typedef int fmi2Status;
typedef void (*fmi2Logger)(void*, const char*, fmi2Status, const char*, const char*, ...);
typedef struct {
    fmi2Logger logger;
    void* (*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void*);
    void (*stepFinished)(void*, fmi2Status);
    void* componentEnvironment;
} fmi2CallbackFunctions;

static void logger(void* env, const char* name, fmi2Status status, const char* category,
                   const char* message, ...)
{
    (void)env;
    va_list args;
    va_start(args, message);
    fprintf(stderr, "[%s|%d|%s] ", name ? name : "", status, category ? category : "");
    vfprintf(stderr, message, args);
    fprintf(stderr, "\n");
    va_end(args);
}

static size_t parse_vrs(const char* text, fmi2ValueReference* out, size_t cap)
{
    size_t n = 0;
    if (strcmp(text, "-") == 0) return 0;
    char* copy = strdup(text);
    for (char* tok = strtok(copy, ","); tok && n < cap; tok = strtok(NULL, ","))
        out[n++] = (fmi2ValueReference)strtoul(tok, NULL, 10);
    free(copy);
    return n;
}

#define CHECK(call)                                                          \
    do {                                                                     \
        fmi2Status s_ = (call);                                              \
        if (s_ > 1) {                                                        \
            fprintf(stderr, "host: %s returned status %d\n", #call, s_);     \
            return 1;                                                        \
        }                                                                    \
    } while (0)

int main(int argc, char** argv)
{
    if (argc < 9) {
        fprintf(stderr, "usage: host FMU_DIR MODEL_IDENTIFIER GUID STEP_SIZE N_STEPS INPUT_FILE "
                        "IN_VRS OUT_VRS [PARAMS]\n");
        return 2;
    }
    const char* dir = argv[1];
    const char* mid = argv[2];
    const char* guid = argv[3];
    double h = strtod(argv[4], NULL);
    long n_steps = strtol(argv[5], NULL, 10);
    fmi2ValueReference in_vrs[256], out_vrs[256], par_vrs[256];
    double par_values[256];
    size_t n_in = parse_vrs(argv[7], in_vrs, 256);
    size_t n_out = parse_vrs(argv[8], out_vrs, 256);
    size_t n_par = 0;
    if (argc > 9 && strlen(argv[9]) > 0) {
        char* copy = strdup(argv[9]);
        for (char* tok = strtok(copy, ","); tok && n_par < 256; tok = strtok(NULL, ",")) {
            char* eq = strchr(tok, '=');
            if (!eq) continue;
            par_vrs[n_par] = (fmi2ValueReference)strtoul(tok, NULL, 10);
            par_values[n_par++] = strtod(eq + 1, NULL);
        }
        free(copy);
    }

    char path[4096];
    snprintf(path, sizeof path, BINARY, dir, mid);
    void* lib = LIB_OPEN(path);
    if (!lib) {
        fprintf(stderr, "host: loading %s failed: %s\n", path, LIB_ERROR());
        return 1;
    }
    typedef fmi2Component (*instantiate_t)(const char*, int, const char*, const char*,
                                           const fmi2CallbackFunctions*, int, int);
    typedef fmi2Status (*setup_t)(fmi2Component, int, double, double, int, double);
    typedef fmi2Status (*component_t)(fmi2Component);
    typedef fmi2Status (*set_real_t)(fmi2Component, const fmi2ValueReference*, size_t, const double*);
    typedef fmi2Status (*get_real_t)(fmi2Component, const fmi2ValueReference*, size_t, double*);
    typedef fmi2Status (*do_step_t)(fmi2Component, double, double, int);
    typedef void (*free_t)(fmi2Component);
#define LOAD(var, type, name)                                                \
    type var = (type)LIB_SYM(lib, name);                                       \
    if (!var) {                                                              \
        fprintf(stderr, "host: missing %s\n", name);                         \
        return 1;                                                            \
    }
    LOAD(instantiate, instantiate_t, "fmi2Instantiate")
    LOAD(setup, setup_t, "fmi2SetupExperiment")
    LOAD(enter_init, component_t, "fmi2EnterInitializationMode")
    LOAD(exit_init, component_t, "fmi2ExitInitializationMode")
    LOAD(set_real, set_real_t, "fmi2SetReal")
    LOAD(get_real, get_real_t, "fmi2GetReal")
    LOAD(do_step, do_step_t, "fmi2DoStep")
    LOAD(terminate, component_t, "fmi2Terminate")
    LOAD(free_instance, free_t, "fmi2FreeInstance")

    double* inputs = calloc((size_t)n_steps * (n_in ? n_in : 1), sizeof(double));
    FILE* f = fopen(argv[6], "r");
    if (!f) {
        fprintf(stderr, "host: cannot open %s\n", argv[6]);
        return 1;
    }
    for (long i = 0; i < n_steps * (long)n_in; ++i) {
        if (fscanf(f, "%lf", &inputs[i]) != 1) {
            fprintf(stderr, "host: input file too short\n");
            return 1;
        }
    }
    fclose(f);

    char uri[4200];
    snprintf(uri, sizeof uri, URI, dir);
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("host", 1 /* fmi2CoSimulation */, guid, uri, &cb, 0, 0);
    if (!c) {
        fprintf(stderr, "host: fmi2Instantiate failed\n");
        return 1;
    }
    CHECK(setup(c, 0, 0.0, 0.0, 0, 0.0));
    if (n_par) CHECK(set_real(c, par_vrs, n_par, par_values));
    CHECK(enter_init(c));
    CHECK(exit_init(c));
    double out[256];
    for (long k = 0; k < n_steps; ++k) {
        if (n_in) CHECK(set_real(c, in_vrs, n_in, &inputs[k * (long)n_in]));
        CHECK(do_step(c, (double)k * h, h, 1));
        CHECK(get_real(c, out_vrs, n_out, out));
        for (size_t j = 0; j < n_out; ++j) {
            uint64_t b;
            memcpy(&b, &out[j], sizeof b);
            printf(j ? " 0x%08lx%08lx" : "0x%08lx%08lx", (unsigned long)(b >> 32),
                   (unsigned long)(b & 0xffffffffu));
        }
        printf("\n");
    }
    CHECK(terminate(c));
    free_instance(c);
    free(inputs);
    return 0;
}
