"""Which names may become C identifiers, Python names and file names.

An arm name is the prefix of every generated C symbol and the name of its
output folder and files, so it must be safe in all three worlds at once. A
name is checked, never rewritten: a rejected name gets the reason.
"""
from __future__ import annotations

import keyword
import re

MAX_LENGTH = 31  # C99 guarantees 31 significant initial characters of external names

_PATTERN = re.compile(r"[a-z][a-z0-9_]*\Z")

C_KEYWORDS = frozenset("""
auto break case char const continue default do double else enum extern float for goto
if inline int long register restrict return short signed sizeof static struct switch
typedef union unsigned void volatile while _Bool _Complex _Imaginary
""".split())

CPP_KEYWORDS = frozenset("""
alignas alignof and and_eq asm bitand bitor bool catch char16_t char32_t char8_t class
compl concept consteval constexpr constinit const_cast co_await co_return co_yield
decltype delete dynamic_cast explicit export false friend mutable namespace new noexcept
not not_eq nullptr operator or or_eq private protected public reinterpret_cast requires
static_assert static_cast template this thread_local throw true try typeid typename
using virtual wchar_t xor xor_eq
""".split())

# Names of the C standard library and libm that a prefix must not shadow, and
# names the generated code or its build uses for itself.
C_LIBRARY = frozenset("""
main abs labs div exit abort malloc calloc realloc free memcpy memset memmove memcmp
strlen strcpy strcmp printf fprintf sprintf snprintf puts putchar stdin stdout stderr
errno assert isnan isinf isfinite nan signbit
sin cos tan asin acos atan atan2 sinh cosh tanh exp log log10 log2 pow sqrt cbrt hypot
fabs floor ceil round trunc fmod fmin fmax fma copysign erf erfc tgamma lgamma
sinf cosf tanf sqrtf fabsf expf logf powf atan2f
j0 j1 jn y0 y1 yn
real int_e theta dtheta yd dyd ddyd params state input gains
""".split())


def name_problem(name: object) -> str | None:
    """Why ``name`` cannot be an arm name, or None when it can.

    Returns a sentence that says what was expected; the caller names the field.
    """
    if not isinstance(name, str):
        return f"a string, got {type(name).__name__} {name!r:.40}"
    shown = repr(name) if len(name) <= 40 else repr(name[:40]) + f"... ({len(name)} characters)"
    if name == "":
        return "a non-empty name, got ''"
    if len(name) > MAX_LENGTH:
        return f"at most {MAX_LENGTH} characters (C99 external names), got {shown}"
    if not _PATTERN.match(name):
        return ("lowercase ASCII letters, digits and '_', starting with a letter "
                f"(a C identifier, a Python name and a file name on every file system), got {shown}")
    if "__" in name or name.endswith("_"):
        return f"no '__' and no trailing '_' (reserved in C++ and by the generated names), got {shown}"
    if name.startswith("casadi"):
        return f"a name that does not start with 'casadi' (CasADi's own prefix), got {shown}"
    for label, words in (("a C keyword", C_KEYWORDS), ("a C++ keyword", CPP_KEYWORDS),
                         ("a C library or generated name", C_LIBRARY)):
        if name in words:
            return f"a name that is not {label}, got {shown}"
    if keyword.iskeyword(name) or keyword.issoftkeyword(name):
        return f"a name that is not a Python keyword, got {shown}"
    return None
