/*
 * C loader for pythonfmu FMUs.
 *
 * pythonfmu's binary leaves the Python C API symbols undefined, so it only loads into
 * a process that already contains Python.  This library is installed as
 * binaries/linux64/<modelIdentifier>.so; pythonfmu's binary sits beside it as
 * <modelIdentifier>_pythonfmu.so.  On first use it
 *   1. loads libpython with RTLD_GLOBAL unless the process already has Python symbols,
 *   2. initialises the interpreter (if nobody did) as the build environment's Python,
 *      so that its site-packages (numpy, scipy, ...) are importable,
 *   3. opens the real binary and forwards every fmi2* call to it,
 *   4. releases pythonfmu's shared interpreter state at exit, before that binary's own
 *      static destructor runs (see release_pythonfmu_state).
 *
 * Compile-time definitions (set by fmutools.loader.compile_loader):
 *   FMUKIT_LIBPYTHON   path of the shared libpython
 *   FMUKIT_EXECUTABLE  path of the Python executable of the build environment
 *   FMUKIT_SITE_DIRS   site-packages folders, separated by '\n'
 *   FMUKIT_REAL_SUFFIX suffix of the real binary ("_pythonfmu.so")
 */
#define _GNU_SOURCE
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FMI2_EXPORT __attribute__((visibility("default")))

typedef void* fmi2Component;
typedef void* fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char* fmi2String;
typedef char fmi2Byte;
typedef int fmi2Status;
typedef int fmi2Type;
typedef int fmi2StatusKind;
typedef void (*fmi2Logger)(void*, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef struct {
    fmi2Logger logger;
    void* (*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void*);
    void (*stepFinished)(void*, fmi2Status);
    void* componentEnvironment;
} fmi2CallbackFunctions;

enum { fmi2OK = 0, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal };

static pthread_once_t g_once = PTHREAD_ONCE_INIT;
static void* g_real = NULL;
static char g_error[1024] = "";

#define FMI_FUNCTIONS(X) \
    X(fmi2GetTypesPlatform) X(fmi2GetVersion) X(fmi2SetDebugLogging) X(fmi2Instantiate) \
    X(fmi2FreeInstance) X(fmi2SetupExperiment) X(fmi2EnterInitializationMode) \
    X(fmi2ExitInitializationMode) X(fmi2Terminate) X(fmi2Reset) X(fmi2GetReal) \
    X(fmi2GetInteger) X(fmi2GetBoolean) X(fmi2GetString) X(fmi2SetReal) X(fmi2SetInteger) \
    X(fmi2SetBoolean) X(fmi2SetString) X(fmi2GetFMUstate) X(fmi2SetFMUstate) \
    X(fmi2FreeFMUstate) X(fmi2SerializedFMUstateSize) X(fmi2SerializeFMUstate) \
    X(fmi2DeSerializeFMUstate) X(fmi2GetDirectionalDerivative) \
    X(fmi2SetRealInputDerivatives) X(fmi2GetRealOutputDerivatives) X(fmi2DoStep) \
    X(fmi2CancelStep) X(fmi2GetStatus) X(fmi2GetRealStatus) X(fmi2GetIntegerStatus) \
    X(fmi2GetBooleanStatus) X(fmi2GetStringStatus)

#define DECLARE_POINTER(name) static void* p_##name = NULL;
FMI_FUNCTIONS(DECLARE_POINTER)

static void set_error(const char* what, const char* detail)
{
    snprintf(g_error, sizeof g_error, "fmukit loader: %s%s%s", what, detail ? ": " : "",
             detail ? detail : "");
}

/* Resolve a Python C API function from the process or from libpython. */
static void* py_symbol(void* lib, const char* name)
{
    void* f = dlsym(lib ? lib : RTLD_DEFAULT, name);
    if (!f) set_error("missing Python symbol", name);
    return f;
}

static int start_python(void)
{
    void* lib = NULL;
    if (!dlsym(RTLD_DEFAULT, "Py_IsInitialized")) {
        lib = dlopen(FMUKIT_LIBPYTHON, RTLD_NOW | RTLD_GLOBAL);
        if (!lib) {
            set_error("cannot load libpython " FMUKIT_LIBPYTHON, dlerror());
            return -1;
        }
    }
    int (*is_initialized)(void) = (int (*)(void))py_symbol(lib, "Py_IsInitialized");
    if (!is_initialized) return -1;
    if (is_initialized()) return 0; /* a Python host (fmpy) or another FMU did it */

    void (*config_init)(PyConfig*) = (void (*)(PyConfig*))py_symbol(lib, "PyConfig_InitPythonConfig");
    PyStatus (*config_set)(PyConfig*, wchar_t**, const char*) =
        (PyStatus(*)(PyConfig*, wchar_t**, const char*))py_symbol(lib, "PyConfig_SetBytesString");
    PyStatus (*init_from_config)(const PyConfig*) =
        (PyStatus(*)(const PyConfig*))py_symbol(lib, "Py_InitializeFromConfig");
    void (*config_clear)(PyConfig*) = (void (*)(PyConfig*))py_symbol(lib, "PyConfig_Clear");
    int (*status_exception)(PyStatus) = (int (*)(PyStatus))py_symbol(lib, "PyStatus_Exception");
    int (*run_string)(const char*) = (int (*)(const char*))py_symbol(lib, "PyRun_SimpleString");
    void* (*save_thread)(void) = (void* (*)(void))py_symbol(lib, "PyEval_SaveThread");
    if (!config_init || !config_set || !init_from_config || !config_clear || !status_exception
        || !run_string || !save_thread)
        return -1;

    PyConfig config;
    config_init(&config);
    config.install_signal_handlers = 0; /* the host owns the signals */
    PyStatus status = config_set(&config, &config.program_name, FMUKIT_EXECUTABLE);
    if (!status_exception(status)) status = config_set(&config, &config.executable, FMUKIT_EXECUTABLE);
    if (!status_exception(status)) status = init_from_config(&config);
    config_clear(&config);
    if (status_exception(status)) {
        set_error("cannot initialise Python", status.err_msg);
        return -1;
    }
    /* The venv is normally found from the executable; add its site dirs explicitly too. */
    static const char code[] =
        "import site, sys\n"
        "for _d in " "'''" FMUKIT_SITE_DIRS "'''" ".split('\\n'):\n"
        "    if _d and _d not in sys.path:\n"
        "        site.addsitedir(_d)\n";
    if (run_string(code) != 0) {
        set_error("cannot add site-packages to sys.path", FMUKIT_SITE_DIRS);
        return -1;
    }
    save_thread(); /* release the GIL: pythonfmu takes it with PyGILState_Ensure */
    return 0;
}

/*
 * pythonfmu keeps its interpreter state in a namespace-scope std::shared_ptr and also
 * resets that pointer from a __attribute__((destructor)) function.  At process exit the
 * C++ static destructor runs first (an atexit handler) and frees the state; the library
 * destructor then resets the already destroyed shared_ptr and decrements freed memory,
 * which corrupts the heap ("free(): corrupted unsorted chunks", SIGABRT, now and then).
 * Resetting the pointer through pythonfmu's own finalizePythonInterpreter from an atexit
 * handler registered after the binary is loaded runs before its static destructor
 * (atexit handlers run last-registered first), so both later resets see a null pointer.
 */
static void (*g_release)(void) = NULL;

static void release_pythonfmu_state(void)
{
    if (g_release) g_release();
}

static void load(void)
{
    if (start_python() != 0) return;
    Dl_info info;
    if (!dladdr((void*)&load, &info) || !info.dli_fname) {
        set_error("cannot locate own library", dlerror());
        return;
    }
    char path[PATH_MAX];
    size_t n = strlen(info.dli_fname);
    if (n < 3 || strcmp(info.dli_fname + n - 3, ".so") != 0
        || n - 3 + strlen(FMUKIT_REAL_SUFFIX) + 1 > sizeof path) {
        set_error("unexpected library name", info.dli_fname);
        return;
    }
    memcpy(path, info.dli_fname, n - 3);
    strcpy(path + n - 3, FMUKIT_REAL_SUFFIX);
    g_real = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!g_real) {
        set_error("cannot load the pythonfmu binary", dlerror());
        return;
    }
#define RESOLVE(name) p_##name = dlsym(g_real, #name);
    FMI_FUNCTIONS(RESOLVE)
    g_release = (void (*)(void))dlsym(g_real, "finalizePythonInterpreter");
    if (g_release) atexit(release_pythonfmu_state);
}

static int ready(void)
{
    pthread_once(&g_once, load);
    if (!g_real && g_error[0]) {
        fprintf(stderr, "%s\n", g_error);
    }
    return g_real != NULL;
}

#define CALL(name, type, ...) \
    ((ready() && p_##name) ? ((type)p_##name)(__VA_ARGS__) : fmi2Error)

FMI2_EXPORT const char* fmi2GetTypesPlatform(void) { return "default"; }
FMI2_EXPORT const char* fmi2GetVersion(void) { return "2.0"; }

FMI2_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
    fmi2String guid, fmi2String resources, const fmi2CallbackFunctions* functions,
    fmi2Boolean visible, fmi2Boolean loggingOn)
{
    if (!ready() || !p_fmi2Instantiate) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Fatal,
                              "logStatusFatal", "%s", g_error[0] ? g_error : "fmukit loader failed");
        return NULL;
    }
    typedef fmi2Component (*f_t)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                 const fmi2CallbackFunctions*, fmi2Boolean, fmi2Boolean);
    return ((f_t)p_fmi2Instantiate)(instanceName, fmuType, guid, resources, functions, visible,
                                    loggingOn);
}

FMI2_EXPORT void fmi2FreeInstance(fmi2Component c)
{
    if (ready() && p_fmi2FreeInstance) ((void (*)(fmi2Component))p_fmi2FreeInstance)(c);
}

typedef fmi2Status (*f_c)(fmi2Component);
FMI2_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return CALL(fmi2EnterInitializationMode, f_c, c); }
FMI2_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return CALL(fmi2ExitInitializationMode, f_c, c); }
FMI2_EXPORT fmi2Status fmi2Terminate(fmi2Component c) { return CALL(fmi2Terminate, f_c, c); }
FMI2_EXPORT fmi2Status fmi2Reset(fmi2Component c) { return CALL(fmi2Reset, f_c, c); }
FMI2_EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { return CALL(fmi2CancelStep, f_c, c); }

FMI2_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[])
{
    return CALL(fmi2SetDebugLogging, fmi2Status (*)(fmi2Component, fmi2Boolean, size_t, const fmi2String*), c, on, n, cats);
}

FMI2_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol,
    fmi2Real start, fmi2Boolean stopDefined, fmi2Real stop)
{
    return CALL(fmi2SetupExperiment, fmi2Status (*)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real),
                c, tolDefined, tol, start, stopDefined, stop);
}

#define GETSET(T)                                                                            \
    FMI2_EXPORT fmi2Status fmi2Get##T(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2##T v[]) \
    {                                                                                        \
        return CALL(fmi2Get##T, fmi2Status (*)(fmi2Component, const fmi2ValueReference*, size_t, fmi2##T*), c, vr, n, v); \
    }                                                                                        \
    FMI2_EXPORT fmi2Status fmi2Set##T(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2##T v[]) \
    {                                                                                        \
        return CALL(fmi2Set##T, fmi2Status (*)(fmi2Component, const fmi2ValueReference*, size_t, const fmi2##T*), c, vr, n, v); \
    }
GETSET(Real)
GETSET(Integer)
GETSET(Boolean)
GETSET(String)

FMI2_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* s)
{
    return CALL(fmi2GetFMUstate, fmi2Status (*)(fmi2Component, fmi2FMUstate*), c, s);
}
FMI2_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s)
{
    return CALL(fmi2SetFMUstate, fmi2Status (*)(fmi2Component, fmi2FMUstate), c, s);
}
FMI2_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* s)
{
    return CALL(fmi2FreeFMUstate, fmi2Status (*)(fmi2Component, fmi2FMUstate*), c, s);
}
FMI2_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t* size)
{
    return CALL(fmi2SerializedFMUstateSize, fmi2Status (*)(fmi2Component, fmi2FMUstate, size_t*), c, s, size);
}
FMI2_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t size)
{
    return CALL(fmi2SerializeFMUstate, fmi2Status (*)(fmi2Component, fmi2FMUstate, fmi2Byte*, size_t), c, s, b, size);
}
FMI2_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t size, fmi2FMUstate* s)
{
    return CALL(fmi2DeSerializeFMUstate, fmi2Status (*)(fmi2Component, const fmi2Byte*, size_t, fmi2FMUstate*), c, b, size, s);
}
FMI2_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
    const fmi2ValueReference k[], size_t nk, const fmi2Real dk[], fmi2Real du[])
{
    return CALL(fmi2GetDirectionalDerivative, fmi2Status (*)(fmi2Component, const fmi2ValueReference*, size_t,
                const fmi2ValueReference*, size_t, const fmi2Real*, fmi2Real*), c, u, nu, k, nk, dk, du);
}
FMI2_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
    const fmi2Integer order[], const fmi2Real v[])
{
    return CALL(fmi2SetRealInputDerivatives, fmi2Status (*)(fmi2Component, const fmi2ValueReference*, size_t,
                const fmi2Integer*, const fmi2Real*), c, vr, n, order, v);
}
FMI2_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
    const fmi2Integer order[], fmi2Real v[])
{
    return CALL(fmi2GetRealOutputDerivatives, fmi2Status (*)(fmi2Component, const fmi2ValueReference*, size_t,
                const fmi2Integer*, fmi2Real*), c, vr, n, order, v);
}
FMI2_EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noPrior)
{
    return CALL(fmi2DoStep, fmi2Status (*)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean), c, t, h, noPrior);
}
FMI2_EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status* v)
{
    return CALL(fmi2GetStatus, fmi2Status (*)(fmi2Component, fmi2StatusKind, fmi2Status*), c, s, v);
}
#define STATUS(T, CT)                                                                        \
    FMI2_EXPORT fmi2Status fmi2Get##T##Status(fmi2Component c, const fmi2StatusKind s, CT* v) \
    {                                                                                        \
        return CALL(fmi2Get##T##Status, fmi2Status (*)(fmi2Component, fmi2StatusKind, CT*), c, s, v); \
    }
STATUS(Real, fmi2Real)
STATUS(Integer, fmi2Integer)
STATUS(Boolean, fmi2Boolean)
STATUS(String, fmi2String)
