/*
 * Minimal FMI 3.0 co-simulation host in plain C (no Python anywhere): host.c for FMI 3.0,
 * with the same command line and output, so tests/support/hosts.py runs either.
 *
 * usage: host3 FMU_DIR MODEL_IDENTIFIER GUID STEP_SIZE N_STEPS INPUT_FILE IN_VRS OUT_VRS [PARAMS]
 *   FMU_DIR     unpacked FMU
 *   INPUT_FILE  N_STEPS rows of len(IN_VRS) numbers (input values before each step)
 *   IN_VRS      comma-separated Real value references of the inputs ("-" for none)
 *   OUT_VRS     comma-separated Real value references of the outputs
 *   PARAMS      optional "vr=value,vr=value" Real start values set before initialisation
 * Prints one line per step: the outputs after the step separated by spaces, as bits.
 * GUID is the instantiation token.  The binary is binaries/x86_64-linux/<id>.so, or built
 * for Windows (mingw-w64) binaries/x86_64-windows/<id>.dll with FMU_DIR a Windows path
 * such as Z:/tmp/fmu.  Outputs are printed as their bits, 0x and 16 hex digits.
 * Exit status 0 on success, 1 on any FMI status above fmi3Warning.
 */
#ifdef _WIN32
#include <windows.h>
#define LIB_OPEN(path) ((void*)LoadLibraryA(path))
#define LIB_SYM(lib, name) ((void*)GetProcAddress((HMODULE)(lib), name))
#define LIB_ERROR() "LoadLibrary failed"
#define BINARY "%s/binaries/x86_64-windows/%s.dll"
#else
#include <dlfcn.h>
#define LIB_OPEN(path) dlopen(path, RTLD_NOW | RTLD_LOCAL)
#define LIB_SYM(lib, name) dlsym(lib, name)
#define LIB_ERROR() dlerror()
#define BINARY "%s/binaries/x86_64-linux/%s.so"
#endif
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void* fmi3Instance;
typedef unsigned int fmi2ValueReference; /* fmi3ValueReference: uint32_t */
typedef int fmi2Status;
typedef void (*fmi3LogMessageCallback)(void*, int, const char*, const char*);

static void logger(void* env, int status, const char* category, const char* message)
{
    (void)env;
    fprintf(stderr, "[%d|%s] %s\n", status, category ? category : "", message ? message : "");
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
    typedef fmi3Instance (*instantiate_t)(const char*, const char*, const char*, bool, bool,
                                          bool, bool, const fmi2ValueReference*, size_t, void*,
                                          fmi3LogMessageCallback, void*);
    typedef fmi2Status (*enter_init_t)(fmi3Instance, bool, double, double, bool, double);
    typedef fmi2Status (*component_t)(fmi3Instance);
    typedef fmi2Status (*set_real_t)(fmi3Instance, const fmi2ValueReference*, size_t,
                                     const double*, size_t);
    typedef fmi2Status (*get_real_t)(fmi3Instance, const fmi2ValueReference*, size_t, double*,
                                     size_t);
    typedef fmi2Status (*do_step_t)(fmi3Instance, double, double, bool, bool*, bool*, bool*,
                                    double*);
    typedef void (*free_t)(fmi3Instance);
#define LOAD(var, type, name)                                                \
    type var = (type)LIB_SYM(lib, name);                                       \
    if (!var) {                                                              \
        fprintf(stderr, "host: missing %s\n", name);                         \
        return 1;                                                            \
    }
    LOAD(instantiate, instantiate_t, "fmi3InstantiateCoSimulation")
    LOAD(enter_init, enter_init_t, "fmi3EnterInitializationMode")
    LOAD(exit_init, component_t, "fmi3ExitInitializationMode")
    LOAD(set_real, set_real_t, "fmi3SetFloat64")
    LOAD(get_real, get_real_t, "fmi3GetFloat64")
    LOAD(do_step, do_step_t, "fmi3DoStep")
    LOAD(terminate, component_t, "fmi3Terminate")
    LOAD(free_instance, free_t, "fmi3FreeInstance")

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

    char resources[4200];
    snprintf(resources, sizeof resources, "%s/resources/", dir);
    fmi3Instance c = instantiate("host", guid, resources, false, false, false, false, NULL, 0,
                                 NULL, logger, NULL);
    if (!c) {
        fprintf(stderr, "host: fmi3InstantiateCoSimulation failed\n");
        return 1;
    }
    if (n_par) CHECK(set_real(c, par_vrs, n_par, par_values, n_par));
    CHECK(enter_init(c, false, 0.0, 0.0, false, 0.0));
    CHECK(exit_init(c));
    double out[256];
    for (long k = 0; k < n_steps; ++k) {
        bool event = false, stop = false, early = false;
        double last = 0.0;
        if (n_in) CHECK(set_real(c, in_vrs, n_in, &inputs[k * (long)n_in], n_in));
        CHECK(do_step(c, (double)k * h, h, true, &event, &stop, &early, &last));
        if (stop || early || last != (double)k * h + h) {
            fprintf(stderr, "host: fmi3DoStep at step %ld: terminate %d, early return %d, "
                    "lastSuccessfulTime %.17g\n", k, stop, early, last);
            return 1;
        }
        CHECK(get_real(c, out_vrs, n_out, out, n_out));
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
