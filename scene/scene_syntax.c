/* scene_syntax.c - strict JSON syntax check that says where and why.
 *
 * Scene text goes through this scan before cJSON parses it. cJSON alone is
 * both too lenient and too vague for a file format: it accepts raw line
 * breaks inside strings and numbers like "01" or "1." (texts other JSON tools
 * refuse, so a scene that loads here would not load elsewhere), and on an
 * error it gives a position but no reason, one character late for a bad
 * object key (the common trailing comma "{"a": 1,}" would read as an
 * unexpected end of text). This small recursive-descent scan follows RFC 8259
 * exactly and stops at the culprit character with what was expected there.
 * A UTF-8 byte order mark is skipped, as cJSON does.
 */
#include <stdlib.h>
#include <string.h>

#include "scene_internal.h"

typedef struct jscan {
    const char *p;   /* current position */
    const char *why; /* set on the first error, with p at the culprit */
    int depth;
} jscan;

static int js_fail(jscan *j, const char *at, const char *why)
{
    j->p = at;
    j->why = why;
    return 0;
}

static void js_ws(jscan *j)
{
    while (*j->p == ' ' || *j->p == '\t' || *j->p == '\r' || *j->p == '\n')
        j->p++;
}

static int js_hex(char ch)
{
    return (ch >= '0' && ch <= '9') || (ch >= 'a' && ch <= 'f') || (ch >= 'A' && ch <= 'F');
}

/* The value of \\uXXXX at p (p[0] is the backslash), or -1. */
static long js_u4(const char *p)
{
    long v = 0;
    for (int k = 2; k < 6; k++) {
        char c = p[k];
        if (!js_hex(c))
            return -1;
        v = 16 * v + (c <= '9' ? c - '0' : (c | 0x20) - 'a' + 10);
    }
    return v;
}

/* Length of the well-formed UTF-8 sequence at p (RFC 3629: no overlong
 * forms, no surrogates, nothing above U+10FFFF), or 0. */
static int js_utf8(const char *s)
{
    const unsigned char *p = (const unsigned char *)s;
    int n;
    unsigned char lo = 0x80, hi = 0xBF;
    if (p[0] >= 0xC2 && p[0] <= 0xDF)
        n = 2;
    else if (p[0] >= 0xE0 && p[0] <= 0xEF) {
        n = 3;
        if (p[0] == 0xE0)
            lo = 0xA0;
        if (p[0] == 0xED)
            hi = 0x9F;
    } else if (p[0] >= 0xF0 && p[0] <= 0xF4) {
        n = 4;
        if (p[0] == 0xF0)
            lo = 0x90;
        if (p[0] == 0xF4)
            hi = 0x8F;
    } else
        return 0;
    if (p[1] < lo || p[1] > hi)
        return 0;
    for (int k = 2; k < n; k++)
        if (p[k] < 0x80 || p[k] > 0xBF)
            return 0;
    return n;
}

static int js_string(jscan *j)
{
    const char *start = j->p;
    if (*j->p != '"')
        return js_fail(j, j->p, *j->p == '\'' ? "strings and keys take double quotes" : "expected a string");
    j->p++;
    for (;;) {
        unsigned char ch = (unsigned char)*j->p;
        if (ch == '\0')
            return js_fail(j, start, "unterminated string (it starts here)");
        if (ch == '"') {
            j->p++;
            return 1;
        }
        if (ch < 0x20)
            return js_fail(j, j->p, ch == '\n' ? "line break inside a string (a missing closing quote?)"
                                               : "control character inside a string (escape it)");
        if (ch == '\\') {
            char e = j->p[1];
            if (e == 'u') {
                long u = js_u4(j->p);
                if (u < 0)
                    return js_fail(j, j->p, "\\u needs 4 hexadecimal digits");
                if (u == 0)
                    return js_fail(j, j->p, "\\u0000 (a NUL character) cannot be in a string: a name would end there");
                if (u >= 0xDC00 && u <= 0xDFFF)
                    return js_fail(j, j->p, "lone low surrogate \\uDC00..\\uDFFF (it must follow a high one)");
                if (u >= 0xD800 && u <= 0xDBFF) {
                    long lo = j->p[6] == '\\' && j->p[7] == 'u' ? js_u4(j->p + 6) : -1;
                    if (lo < 0xDC00 || lo > 0xDFFF)
                        return js_fail(j, j->p,
                                       "lone high surrogate \\uD800..\\uDBFF (it must be followed by a low one)");
                    j->p += 6;
                }
                j->p += 6;
                continue;
            }
            if (!e || !strchr("\"\\/bfnrt", e))
                return js_fail(j, j->p,
                               "invalid escape in a string (allowed: \\\" \\\\ \\/ \\b \\f \\n \\r \\t \\uXXXX)");
            j->p += 2;
            continue;
        }
        if (ch >= 0x80) {
            int n = js_utf8(j->p);
            if (n == 0)
                return js_fail(j, j->p, "invalid UTF-8 in a string (scene files are UTF-8 text)");
            j->p += n;
            continue;
        }
        j->p++;
    }
}

static int js_value(jscan *j);

static int js_object(jscan *j)
{
    j->p++; /* '{' */
    js_ws(j);
    if (*j->p == '}') {
        j->p++;
        return 1;
    }
    for (;;) {
        js_ws(j);
        if (*j->p == '}')
            return js_fail(j, j->p, "a comma before '}' (JSON allows no trailing comma)");
        if (*j->p == '\0')
            return js_fail(j, j->p, "unexpected end of the text inside an object");
        if (*j->p != '"' && *j->p != '\'')
            return js_fail(j, j->p, "expected a key in double quotes");
        if (!js_string(j))
            return 0;
        js_ws(j);
        if (*j->p != ':')
            return js_fail(j, j->p, "expected ':' after the key");
        j->p++;
        js_ws(j);
        if (!js_value(j))
            return 0;
        js_ws(j);
        if (*j->p == ',') {
            j->p++;
            continue;
        }
        if (*j->p == '}') {
            j->p++;
            return 1;
        }
        return js_fail(j, j->p, *j->p ? "expected ',' or '}' after a value"
                                      : "unexpected end of the text inside an object (a missing '}'?)");
    }
}

static int js_array(jscan *j)
{
    j->p++; /* '[' */
    js_ws(j);
    if (*j->p == ']') {
        j->p++;
        return 1;
    }
    for (;;) {
        js_ws(j);
        if (*j->p == ']')
            return js_fail(j, j->p, "a comma before ']' (JSON allows no trailing comma)");
        if (!js_value(j))
            return 0;
        js_ws(j);
        if (*j->p == ',') {
            j->p++;
            continue;
        }
        if (*j->p == ']') {
            j->p++;
            return 1;
        }
        return js_fail(j, j->p, *j->p ? "expected ',' or ']' after a value"
                                      : "unexpected end of the text inside an array (a missing ']'?)");
    }
}

static int js_value(jscan *j)
{
    const char *p = j->p;
    switch (*p) {
    case '{':
    case '[': {
        if (++j->depth > CJSON_NESTING_LIMIT)
            return js_fail(j, p, "nested too deeply");
        int ok = *p == '{' ? js_object(j) : js_array(j);
        j->depth--;
        return ok;
    }
    case '"': return js_string(j);
    case '\0': return js_fail(j, p, "unexpected end of the text where a value should be");
    default: break;
    }
    if (strncmp(p, "true", 4) == 0 || strncmp(p, "null", 4) == 0) {
        j->p += 4;
        return 1;
    }
    if (strncmp(p, "false", 5) == 0) {
        j->p += 5;
        return 1;
    }
    if (strncmp(p, "NaN", 3) == 0 || strncmp(p, "Infinity", 8) == 0 || strncmp(p, "-Infinity", 9) == 0 ||
        strncmp(p, "nan", 3) == 0 || strncmp(p, "inf", 3) == 0 || strncmp(p, "-inf", 4) == 0)
        return js_fail(j, p, "NaN and infinities are not JSON numbers");
    /* Numbers by the JSON grammar: -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?
     * (cJSON alone would take "01", "1." and "1e" through strtod). */
    if (*p == '-' || (*p >= '0' && *p <= '9')) {
        const char *q = p;
        if (*q == '-')
            q++;
        if (*q == '0')
            q++;
        else if (*q >= '1' && *q <= '9')
            while (*q >= '0' && *q <= '9')
                q++;
        else
            return js_fail(j, p, "a number needs digits after '-'");
        if (*q >= '0' && *q <= '9')
            return js_fail(j, p, "a number cannot have a leading zero");
        if (*q == '.') {
            q++;
            if (!(*q >= '0' && *q <= '9'))
                return js_fail(j, p, "a number needs digits after '.'");
            while (*q >= '0' && *q <= '9')
                q++;
        }
        if (*q == 'e' || *q == 'E') {
            q++;
            if (*q == '+' || *q == '-')
                q++;
            if (!(*q >= '0' && *q <= '9'))
                return js_fail(j, p, "a number needs digits in its exponent");
            while (*q >= '0' && *q <= '9')
                q++;
        }
        /* cJSON reads at most 63 characters of a number and would stop inside
         * a longer one; no double needs more. */
        if (q - p > 63)
            return js_fail(j, p, "a number longer than 63 characters (more digits than a double holds)");
        j->p = q;
        return 1;
    }
    return js_fail(j, p,
                   "expected a value (a number, a string in double quotes, an object, an array, true, false or null)");
}

const char *sp_json_locate(const char *text, const char **why)
{
    jscan j = {text, NULL, 0};
    if ((unsigned char)j.p[0] == 0xEF && (unsigned char)j.p[1] == 0xBB && (unsigned char)j.p[2] == 0xBF)
        j.p += 3;
    js_ws(&j);
    if (js_value(&j)) {
        js_ws(&j);
        if (*j.p == '\0')
            return NULL;
        js_fail(&j, j.p, "unexpected text after the end of the JSON value");
    }
    *why = j.why;
    return j.p;
}
