/* The CPython C API through dlsym (GetProcAddress on Windows), and the runtime's few
 * Python-side helpers.
 * 
 *
 * Written by hand because no library does it: the runtime must serve whichever CPython
 * the host runs or the runtime finds (3.9 and later), so it cannot link one libpython,
 * and it uses only exported functions (macros and struct layouts differ between
 * versions).
 */
#include "python.h"

#include "loader.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PY_FILE_INPUT 257 /* Py_file_input of CPython's compile.h, the same in every 3.x */

PythonApi py;

/* The helpers run in a module of their own (not __main__, which a Python host owns), and
 * never through sys.path: the FMU's package is found in its own resources folder only.
 * Their first lines, before any import of an FMU's code: CPython 3.13.0's collections/abc.py
 * puts _collections_abc in its own place in sys.modules as it runs, and a thread importing
 * collections.abc while another thread did got that stand-in, without the names ("cannot
 * import name 'Callable' from 'collections.abc'", an instantiation failed: two FMUs
 * instantiated at once from a parallel master's threads). They put _collections_abc there
 * first, as collections/__init__.py does itself from 3.13.1 on.
 * The FMU's modules are loaded by a loader that writes no bytecode (_Loader, with a
 * FileFinder of its own for each folder of the package, where its submodules are found):
 * the extraction is the host's folder, perhaps shared or read-only, and a Python of another
 * minor version than the build's (whose .pyc files the FMU ships) wrote its own .pyc files
 * into __pycache__ folders there. Such a Python compiles the modules once per process
 * instead (about 0.1 s an FMU). */
static const char HELPERS[] =
    "import importlib, importlib.machinery, importlib.util, os, sys\n"
    "\n"
    "if sys.version_info[:3] == (3, 13, 0):\n"
    "    import _collections_abc, collections\n"
    "    sys.modules.setdefault('collections.abc', _collections_abc)\n"
    "    collections.abc = _collections_abc\n"
    "\n"
    "\n"
    "def check():\n"
    "    import importlib.util\n"
    "    if importlib.util.find_spec('numpy') is None:\n"
    "        exe = sys.executable or 'python'\n"
    "        return 'it cannot import numpy (fix: %s -m pip install numpy)' % exe\n"
    "    return ''\n"
    "\n"
    "\n"
    "def configure(path, executable):\n"
    "    import site\n"
    "    sys.path[:] = path\n"
    "    for entry in path:\n"
    "        if entry.endswith(('site-packages', 'dist-packages')):\n"
    "            site.addsitedir(entry)\n"
    "    if executable:\n"
    "        sys.executable = executable\n"
    "\n"
    "\n"
    "class _Loader(importlib.machinery.SourceFileLoader):\n"
    "    def set_data(self, path, data, *, _mode=0o666):\n"
    "        pass\n"
    "\n"
    "\n"
    "def _finder(folder):\n"
    "    sources = (_Loader, importlib.machinery.SOURCE_SUFFIXES)\n"
    "    return importlib.machinery.FileFinder(folder, sources)\n"
    "\n"
    "\n"
    "def load(package, resources, module, name):\n"
    "    if package not in sys.modules:\n"
    "        spec = _finder(resources).find_spec(package)\n"
    "        if spec is None or not spec.submodule_search_locations:\n"
    "            raise ImportError('no package %s in %s' % (package, resources))\n"
    "        for folder, subfolders, _ in os.walk(spec.submodule_search_locations[0]):\n"
    "            subfolders[:] = [s for s in subfolders if s != '__pycache__']\n"
    "            sys.path_importer_cache[folder] = _finder(folder)\n"
    "        top = importlib.util.module_from_spec(spec)\n"
    "        sys.modules[package] = top\n"
    "        try:\n"
    "            spec.loader.exec_module(top)\n"
    "        except BaseException:\n"
    "            del sys.modules[package]\n"
    "            raise\n"
    "    return getattr(importlib.import_module(module), name)\n";

static PyObject *helpers; /* the helpers' namespace (never released: Python outlives it) */

typedef struct {
    const char *name;
    void **slot;
} Symbol;

#define SYMBOL(field, name) {name, (void **)&py.field}

int python_resolve(void *library, const char **missing)
{
    const Symbol symbols[] = {
        SYMBOL(IsInitialized, "Py_IsInitialized"),
        SYMBOL(GetVersion, "Py_GetVersion"),
        SYMBOL(DecodeLocale, "Py_DecodeLocale"),
        SYMBOL(SetPythonHome, "Py_SetPythonHome"),
        SYMBOL(InitializeEx, "Py_InitializeEx"),
        SYMBOL(RawFree, "PyMem_RawFree"),
        SYMBOL(SaveThread, "PyEval_SaveThread"),
        SYMBOL(GILState_Ensure, "PyGILState_Ensure"),
        SYMBOL(GILState_Release, "PyGILState_Release"),
        SYMBOL(IncRef, "Py_IncRef"),
        SYMBOL(DecRef, "Py_DecRef"),
        SYMBOL(None, "_Py_NoneStruct"),
        SYMBOL(GetAttrString, "PyObject_GetAttrString"),
        SYMBOL(Call, "PyObject_Call"),
        SYMBOL(CallFunctionObjArgs, "PyObject_CallFunctionObjArgs"),
        SYMBOL(GetBuffer, "PyObject_GetBuffer"),
        SYMBOL(Buffer_Release, "PyBuffer_Release"),
        SYMBOL(IsTrue, "PyObject_IsTrue"),
        SYMBOL(Str, "PyObject_Str"),
        SYMBOL(Float_FromDouble, "PyFloat_FromDouble"),
        SYMBOL(Float_AsDouble, "PyFloat_AsDouble"),
        SYMBOL(Long_FromLong, "PyLong_FromLong"),
        SYMBOL(Long_FromUnsignedLong, "PyLong_FromUnsignedLong"),
        SYMBOL(Long_AsLong, "PyLong_AsLong"),
        SYMBOL(Bool_FromLong, "PyBool_FromLong"),
        SYMBOL(Unicode_FromString, "PyUnicode_FromString"),
        SYMBOL(Unicode_DecodeFSDefault, "PyUnicode_DecodeFSDefault"),
        SYMBOL(Unicode_AsUTF8, "PyUnicode_AsUTF8"),
        SYMBOL(Bytes_FromStringAndSize, "PyBytes_FromStringAndSize"),
        SYMBOL(Bytes_AsStringAndSize, "PyBytes_AsStringAndSize"),
        SYMBOL(List_New, "PyList_New"),
        SYMBOL(List_SetItem, "PyList_SetItem"),
        SYMBOL(List_GetItem, "PyList_GetItem"),
        SYMBOL(List_Size, "PyList_Size"),
        SYMBOL(List_SetSlice, "PyList_SetSlice"),
        SYMBOL(Tuple_New, "PyTuple_New"),
        SYMBOL(Tuple_SetItem, "PyTuple_SetItem"),
        SYMBOL(Tuple_GetItem, "PyTuple_GetItem"),
        SYMBOL(Tuple_Size, "PyTuple_Size"),
        SYMBOL(Dict_New, "PyDict_New"),
        SYMBOL(Dict_SetItemString, "PyDict_SetItemString"),
        SYMBOL(Dict_SetItem, "PyDict_SetItem"),
        SYMBOL(Module_New, "PyModule_New"),
        SYMBOL(Module_GetDict, "PyModule_GetDict"),
        SYMBOL(Import_ImportModule, "PyImport_ImportModule"),
        SYMBOL(Import_AddModule, "PyImport_AddModule"),
        SYMBOL(SetAttrString, "PyObject_SetAttrString"),
        SYMBOL(Long_FromVoidPtr, "PyLong_FromVoidPtr"),
        SYMBOL(Set_New, "PySet_New"),
        SYMBOL(Set_Add, "PySet_Add"),
        SYMBOL(Set_Contains, "PySet_Contains"),
        SYMBOL(Set_Discard, "PySet_Discard"),
        SYMBOL(CompileString, "Py_CompileString"),
        SYMBOL(Eval_EvalCode, "PyEval_EvalCode"),
        SYMBOL(Err_Occurred, "PyErr_Occurred"),
        SYMBOL(Err_Fetch, "PyErr_Fetch"),
        SYMBOL(Err_Clear, "PyErr_Clear"),
    };
    for (size_t i = 0; i < sizeof symbols / sizeof symbols[0]; i++) {
        *symbols[i].slot = platform_library_symbol(library, symbols[i].name);
        if (!*symbols[i].slot) {
            *missing = symbols[i].name;
            return 0;
        }
    }
    *(void **)&py.UTF8Mode = platform_library_symbol(library, "Py_UTF8Mode");
    /* public from 3.13; the private name before: either tells a shutdown in progress */
    *(void **)&py.IsFinalizing = platform_library_symbol(library, "Py_IsFinalizing");
    if (!py.IsFinalizing) {
        *(void **)&py.IsFinalizing = platform_library_symbol(library, "_Py_IsFinalizing");
    }
    return 1;
}

int python_alive(void)
{
    return py.IsInitialized && py.IsInitialized() && !(py.IsFinalizing && py.IsFinalizing());
}

int python_gone(void) { return py.IsInitialized && !python_alive(); }

int python_version(int *major, int *minor, char *said, size_t size)
{
    const char *version = py.GetVersion ? py.GetVersion() : "";
    int v[3];
    int ok = read_version(version, 2, 0, v);
    *major = v[0];
    *minor = v[1];
    size_t word = strcspn(version, " ");
    snprintf(said, size, "%.*s", (int)whole_characters(version, word < 64 ? word : 64),
             version);
    return ok;
}

PyObject *python_none(void)
{
    py.IncRef(py.None);
    return py.None;
}

PyObject *python_helper(const char *name)
{
    if (!helpers) {
        PyObject *module = py.Module_New("auv_fmu_runtime_helpers");
        PyObject *builtins = py.Import_ImportModule("builtins");
        PyObject *code = py.CompileString(HELPERS, "<auv-fmu-runtime>", PY_FILE_INPUT);
        PyObject *namespace = module ? py.Module_GetDict(module) : NULL; /* borrowed */
        PyObject *done = NULL;
        if (namespace && builtins && code &&
            py.Dict_SetItemString(namespace, "__builtins__", builtins) == 0) {
            done = py.Eval_EvalCode(code, namespace, namespace);
        }
        if (done) {
            helpers = module; /* kept: it owns the namespace */
            module = NULL;
            py.DecRef(done);
        }
        if (module) py.DecRef(module);
        if (builtins) py.DecRef(builtins);
        if (code) py.DecRef(code);
        if (!helpers) return NULL;
    }
    return py.GetAttrString(helpers, name);
}

int python_states(int what, void *state)
{
    if (!python_alive()) return 0;
    int gil = py.GILState_Ensure();
    PyObject *module = py.Import_AddModule("auv_fmu_runtime_states"); /* borrowed */
    PyObject *alive = module ? py.GetAttrString(module, "alive") : NULL;
    if (module && !alive) { /* the first state in the process */
        py.Err_Clear();
        alive = py.Set_New(NULL);
        if (alive && py.SetAttrString(module, "alive", alive) != 0) {
            py.DecRef(alive);
            alive = NULL;
        }
    }
    PyObject *key = alive ? py.Long_FromVoidPtr(state) : NULL;
    int done = 0;
    if (key) {
        done = what == STATE_KEEP     ? py.Set_Add(alive, key) == 0
               : what == STATE_FORGET ? py.Set_Discard(alive, key) == 1
                                      : py.Set_Contains(alive, key) == 1;
    }
    py.Err_Clear();
    if (key) py.DecRef(key);
    if (alive) py.DecRef(alive);
    py.GILState_Release(gil);
    return done;
}

void python_error(char *out, size_t size)
{
    PyObject *type = NULL, *value = NULL, *traceback = NULL;
    py.Err_Fetch(&type, &value, &traceback);
    const char *kind = "error";
    PyObject *name = type ? py.GetAttrString(type, "__name__") : NULL;
    PyObject *text = value ? py.Str(value) : NULL;
    if (name) kind = py.Unicode_AsUTF8(name);
    const char *message = text ? py.Unicode_AsUTF8(text) : NULL;
    snprintf(out, size, "%s: %s", kind ? kind : "error", message ? message : "(no message)");
    py.Err_Clear(); /* a failed str() or attribute lookup above leaves its own */
    PyObject *objects[] = {name, text, type, value, traceback};
    for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++) {
        if (objects[i]) py.DecRef(objects[i]);
    }
}
