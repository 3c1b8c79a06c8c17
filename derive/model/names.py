"""Which names may become C identifiers, Python names and file names.

An arm name is the prefix of every generated C symbol, a CMake target and the
name of its output folder, files and Python module, so it must be safe in all
those worlds at once: a C (and C++) identifier of at most 31 characters of
lowercase ASCII letters, digits and '_' (macOS and Windows fold case, so names
differing only by case would share a folder), not a C, C++ or Python keyword,
not a C library, CasADi, CMake, Python builtin or module, or Windows device
name, and no clash with the names derive generates across arms (arm
'x_kernel' would make the kernel names of arm 'x'). A name is checked, never
rewritten: a rejected name gets the reason, naming an offending character by
its code point so that look-alikes (Cyrillic 'а') and invisible ones show.

The names derive generates inside an arm's code never meet the arm name, by
construction: every identifier the generated C declares at file scope (and every
CMake target and variable) is the arm name followed by '_' and one of
GENERATED_SUFFIXES (macros: its upper case), the arm name itself is never an
identifier of the generated C or Python (it is a file, module, project and target
name only), and ports, parameters, statics and CSE registers (theta, dt, u, z, w1,
k1, a0, jsolve1, clip, ...) are locals, struct fields or statics of a .c file. So an
arm may be named like a derived symbol: 'z1' (the Unitree Z1), 'e', 'dt', 'u',
'theta1', 'w1' (tests/test_names.py compiles and runs such arms with -Wshadow -Werror).
"""
from __future__ import annotations

import builtins
import keyword
import reprlib
import sys
import unicodedata

MAX_LENGTH = 31  # C99 5.2.4.1: 31 significant initial characters of an external name

_ALLOWED = frozenset("abcdefghijklmnopqrstuvwxyz0123456789_")

C_KEYWORDS = frozenset("""
auto break case char const continue default do double else enum extern float for goto
if inline int long register restrict return short signed sizeof static struct switch
typedef union unsigned void volatile while
alignas alignof bool constexpr false nullptr static_assert thread_local true typeof
typeof_unqual
""".split())  # C99, and the lowercase keywords C23 adds

CPP_KEYWORDS = frozenset("""
alignas alignof and and_eq asm bitand bitor bool catch char16_t char32_t char8_t class
compl concept consteval constexpr constinit const_cast co_await co_return co_yield
decltype delete dynamic_cast explicit export false friend mutable namespace new noexcept
not not_eq nullptr operator or or_eq private protected public reinterpret_cast requires
static_assert static_cast template this thread_local throw true try typeid typename
using virtual wchar_t xor xor_eq final override import module
""".split())

# The C standard library (C99/C11 functions and macros a prefix must not shadow),
# the common POSIX names the build links against, and main.
C_LIBRARY = frozenset("""
main abort abs atexit at_quick_exit atof atoi atol atoll bsearch calloc div exit _exit
free getenv labs ldiv llabs lldiv malloc mblen mbstowcs mbtowc qsort quick_exit rand
realloc srand strtod strtof strtol strtold strtoll strtoul strtoull system wcstombs wctomb
aligned_alloc memchr memcmp memcpy memmove memset strcat strchr strcmp strcoll strcpy
strcspn strerror strlen strncat strncmp strncpy strpbrk strrchr strspn strstr strtok
strxfrm strdup strndup clearerr fclose feof ferror fflush fgetc fgetpos fgets fopen
fprintf fputc fputs fread freopen fscanf fseek fsetpos ftell fwrite getc getchar gets
perror printf putc putchar puts remove rename rewind scanf setbuf setvbuf snprintf
sprintf sscanf tmpfile tmpnam ungetc vfprintf vprintf vsnprintf vsprintf stdin stdout
stderr errno assert offsetof setjmp longjmp signal raise va_start va_end va_arg va_copy
isalnum isalpha isblank iscntrl isdigit isgraph islower isprint ispunct isspace isupper
isxdigit tolower toupper clock difftime mktime time asctime ctime gmtime localtime
strftime setlocale localeconv
acos acosh asin asinh atan atan2 atanh cbrt ceil copysign cos cosh erf erfc exp exp2
expm1 fabs fdim floor fma fmax fmin fmod frexp hypot ilogb ldexp lgamma llrint llround
log log10 log1p log2 logb lrint lround modf nan nearbyint nextafter nexttoward pow
remainder remquo rint round scalbln scalbn sin sinh sqrt tan tanh tgamma trunc
fpclassify isfinite isinf isnan isnormal signbit isgreater isless
sinf cosf tanf sqrtf fabsf expf logf powf atan2f floorf ceilf fminf fmaxf hypotf
sinl cosl tanl sqrtl fabsl expl logl powl
j0 j1 jn y0 y1 yn gamma drem finite
open close read write link unlink kill wait fork pipe stat sleep index rindex random
select poll times dup
""".split())

# Names CasADi's generated C uses unprefixed (its kernel arguments and work
# vectors); everything CasADi defines itself starts with "casadi".
CASADI_NAMES = frozenset("arg res iw w mem sz_arg sz_res sz_iw sz_w f0 s0 sq".split())

# What the templates append to an arm name (lowercase; macros use it upper-cased):
# <arm>_real, <arm>_kernel_gains, <ARM>_KERNELS_H, files <arm>_kernels.c, target <arm>_selftest,
# the plant's <arm>_mass_matrix, <arm>_plant.c, target <arm>_plant_selftest; the regressor's
# (derive generate --regressor) <arm>_regressor, <ARM>_REGRESSOR_H, <ARM>_NB; the CMake variables
# <ARM>_BUILD_TESTS, <ARM>_INSTALL, <ARM>_TOP_LEVEL, <ARM>_CMAKE_DIR.
GENERATED_SUFFIXES = frozenset("""
real input params params_default gains mpc_step npid_state npid_init npid_step dobc_state mask
dobc_init dobc_step kernels kernel_gains kernel_mpc kernel_npid kernel_dobc kernel_dobc_factor kernel_observer
kernel_dobc_init dobc_estimate kernel_dhat selftest h n np ok enonfinite edt kernels_h
mass_matrix bias gravity input_matrix forward_dynamics plant plant_h plant_selftest plant_kernel_mass_matrix
plant_kernel_bias plant_kernel_gravity plant_kernel_input_matrix plant_kernel_forward_dynamics
build_tests install top_level cmake_dir
mom_state mom_init mom_step mom_estimate kernel_mom kernel_mom_next kernel_mom_init
regressor regressor_h regressor_selftest regressor_kernel base_names base_values nb
""".split())
# A name ending in _<tail> would make the same names as the arm without it: arm x_kernel's
# x_kernel_gains is arm x's kernel; x_kernels.h and the x_selftest target are arm x's files.
CLASHING_TAILS = frozenset({s2[: -len(s1) - 1] for s2 in GENERATED_SUFFIXES for s1 in GENERATED_SUFFIXES
                            if s2.endswith("_" + s1)} | {"kernels", "selftest"})

# Target names CMake reserves (the arm name is a CMake project and library target).
CMAKE_TARGETS = frozenset("""
all clean help install test package package_source edit_cache rebuild_cache
list_install_components depend preinstall install_strip install_local
""".split())

WINDOWS_DEVICES = frozenset("con prn aux nul".split() + [f"{d}{i}" for d in ("com", "lpt") for i in range(1, 10)])

PYTHON_MODULES = frozenset(sys.stdlib_module_names) | frozenset(
    "casadi numpy sympy jinja2 pytest hypothesis scipy pinocchio pin derive".split())
PYTHON_BUILTINS = frozenset(n for n in dir(builtins) if not n.startswith("_"))


def _shown(name: str) -> str:
    """The name as the message shows it: quoted, escaped, cut after 40 characters."""
    if len(name) <= 40:
        return repr(name)
    return f"{name[:40]!r}... ({len(name)} characters)"


def _character(ch: str) -> str:
    """A character named so that look-alikes and invisible ones are told apart."""
    code = f"U+{ord(ch):04X}"
    label = unicodedata.name(ch, "")
    if not label:
        label = {0: "NUL", 9: "TAB", 10: "LINE FEED", 13: "CARRIAGE RETURN", 27: "ESCAPE"}.get(
            ord(ch), "a control character")
    shown = repr(ch) if ch.isprintable() else ascii(ch)
    return f"{shown} ({code} {label})"


def _bad_character(name: str) -> str | None:
    """The rule a character of ``name`` breaks, or None when all are allowed."""
    upper = [c for c in name if "A" <= c <= "Z"]
    for i, ch in enumerate(name):
        if ch in _ALLOWED or ch in upper:
            continue
        where = f"at position {i + 1}"
        if not ch.isprintable():
            return (f"only a-z, 0-9 and '_' (no control or invisible characters), "
                    f"found {_character(ch)} {where}")
        if ord(ch) > 127:
            ascii_twin = unicodedata.normalize("NFKD", ch).encode("ascii", "ignore").decode()
            hint = f", which looks like {ascii_twin!r}" if ascii_twin.strip() else ""
            return (f"only ASCII a-z, 0-9 and '_' (C identifiers and portable file names are "
                    f"ASCII: spell Greek letters out, as in 'theta_arm'), found {_character(ch)} {where}{hint}")
        return f"only a-z, 0-9 and '_' (a C identifier and a file name), found {ch!r} {where}"
    if upper:
        first = next(i for i, c in enumerate(name) if c in upper)
        return ("lowercase letters only (the project requires lowercase names: names that differ "
                f"only by case are one folder on macOS and Windows), found {name[first]!r} at position "
                f"{first + 1} (write {name.lower()[:40]!r})")
    return None


def name_check(name: object) -> tuple[str, str] | None:
    """(what an arm name must be, the given name as shown) when ``name`` is
    rejected, or None when it is a valid arm name."""
    if not isinstance(name, str):
        kind = {dict: "table", list: "array", bool: "boolean"}.get(type(name), type(name).__name__)
        try:
            shown = reprlib.repr(name)
        except Exception:  # noqa: BLE001 - e.g. an int beyond str()'s digit limit: shown by type
            shown = "..."
        return "a string (a lowercase C identifier)", f"{kind} {shown}"
    shown = _shown(name)
    if name == "":
        return "a non-empty name (a lowercase C identifier)", "''"
    why = _bad_character(name)
    if why is None and len(name) > MAX_LENGTH:
        why = f"at most {MAX_LENGTH} characters (C99 significant length of external names)"
    if why is None and name[0].isdigit():
        why = "a name that starts with a letter (a C identifier cannot start with a digit)"
    if why is None and name[0] == "_":
        why = "a name that starts with a letter (leading '_' is reserved in C)"
    if why is None and ("__" in name or name.endswith("_")):
        why = "no '__' and no trailing '_' (reserved in C++; '_' joins the generated names)"
    if why is None and name.endswith("_t"):
        why = "a name that does not end in '_t' (POSIX reserves it for type names)"
    if why is None:
        why = _reserved(name)
    return None if why is None else (why, shown)


def _reserved(name: str) -> str | None:
    """Why ``name``, a well-formed identifier, is taken by someone else, or None."""
    if name.startswith("casadi"):
        return "a name that does not start with 'casadi' (CasADi's own prefix)"
    for label, words in (("a C keyword", C_KEYWORDS), ("a C++ keyword", CPP_KEYWORDS),
                         ("a C standard library name", C_LIBRARY),
                         ("a name CasADi's generated code uses", CASADI_NAMES)):
        if name in words:
            return f"a name that is not {label}"
    tail = next((t for t in CLASHING_TAILS if name.endswith("_" + t)), None)
    if tail is not None:
        return (f"a name that does not end in '_{tail}' (its generated names would collide with those "
                f"of an arm named {name[: -len(tail) - 1]!r})")
    if name in CMAKE_TARGETS:
        return "a name that is not a target name CMake reserves"
    if keyword.iskeyword(name) or keyword.issoftkeyword(name):
        return "a name that is not a Python keyword"
    if name in PYTHON_BUILTINS:
        return "a name that is not a Python builtin"
    if name in PYTHON_MODULES:
        return "a name that is not a Python module name (the generated module would shadow it)"
    if name in WINDOWS_DEVICES:
        return "a name that is not a device name Windows reserves for files (con, nul, com1, ...)"
    return None


def name_problem(name: object) -> str | None:
    """Why ``name`` cannot be an arm name, or None when it can.

    Returns a sentence "<what a name must be>, got <the name>"; the caller
    names the field.
    """
    found = name_check(name)
    return None if found is None else f"{found[0]}, got {found[1]}"
