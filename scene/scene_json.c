/* scene_json.c - JSON text to cJSON tree, "--set" overrides, typed getters.
 *
 * cJSON is permissive in ways a scene file must not be: it keeps duplicate
 * keys (and reads the first), turns 1e999 into infinity, and reports syntax
 * errors as a bare pointer. The getters here close those gaps so that the
 * stages above only ever see checked, finite values.
 */
#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <string.h>

#include "scene_internal.h"

/* Integers travel through JSON as doubles; above 2^53 they are not exact. */
#define SP_INT_EXACT 9007199254740992.0

rr_status sp_fail(const sp_ctx *c, rr_status code, const char *path, const char *fmt, ...)
{
    char what[RR_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    if (path && path[0])
        return rr_error_set(c->err, code, "%s: %s: %s", c->file, path, what);
    return rr_error_set(c->err, code, "%s: %s", c->file, what);
}

/* Paths longer than SP_PATH_MAX are cut (snprintf already terminates them);
 * looking at the length keeps -Wformat-truncation honest about it. */
static void sp_cut(char *out, int n)
{
    if (n < 0)
        out[0] = '\0';
}

void sp_key(char *out, const char *parent, const char *key)
{
    if (parent && parent[0])
        sp_cut(out, snprintf(out, SP_PATH_MAX, "%s.%s", parent, key));
    else
        sp_cut(out, snprintf(out, SP_PATH_MAX, "%s", key));
}

void sp_idx(char *out, const char *parent, size_t i) { sp_cut(out, snprintf(out, SP_PATH_MAX, "%s[%zu]", parent, i)); }

const char *sp_describe(const cJSON *v, char *buf, size_t n)
{
    if (!v)
        snprintf(buf, n, "nothing");
    else if (cJSON_IsNull(v))
        snprintf(buf, n, "null");
    else if (cJSON_IsBool(v))
        snprintf(buf, n, "%s", cJSON_IsTrue(v) ? "true" : "false");
    else if (cJSON_IsNumber(v))
        snprintf(buf, n, "the number %g", v->valuedouble);
    else if (cJSON_IsString(v))
        snprintf(buf, n, "the string \"%.40s%s\"", v->valuestring, strlen(v->valuestring) > 40 ? "..." : "");
    else if (cJSON_IsArray(v))
        snprintf(buf, n, "an array of %d item%s", cJSON_GetArraySize(v), cJSON_GetArraySize(v) == 1 ? "" : "s");
    else if (cJSON_IsObject(v))
        snprintf(buf, n, "an object");
    else
        snprintf(buf, n, "an unknown value");
    return buf;
}

/* ---- text to tree ---- */

rr_status sp_parse_text(const sp_ctx *c, const char *text, cJSON **root)
{
    const char *p = text;
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n')
        p++;
    if (*p == '\0')
        return sp_fail(c, RR_ERR_PARSE, "", "the file is empty (expected a JSON object with \"format\": \"%s\")",
                       SCENE_FORMAT);
    /* Strict syntax first (exact place and reason), then cJSON builds the
     * tree; text that passed the scan can only fail in cJSON for memory. */
    const char *why = NULL;
    const char *at = sp_json_locate(text, &why);
    if (!at) {
        cJSON *j = cJSON_ParseWithOpts(text, NULL, 1);
        if (!j)
            return sp_fail(c, RR_ERR_NOMEM, "", "out of memory parsing the JSON text");
        *root = j;
        return RR_OK;
    }
    /* Offset to line:column (1-based, columns in bytes) for an editor. */
    long line = 1, col = 1;
    for (const char *q = text; q < at && *q; q++) {
        if (*q == '\n') {
            line++;
            col = 1;
        } else {
            col++;
        }
    }
    if (*at == '\0')
        return rr_error_set(c->err, RR_ERR_PARSE, "%s:%ld:%ld: invalid JSON at the end of the text: %s", c->file, line,
                            col, why);
    char near[32];
    size_t k = 0;
    for (const char *q = at; *q && *q != '\n' && *q != '\r' && k < 24; q++)
        near[k++] = isprint((unsigned char)*q) ? *q : '?';
    near[k] = '\0';
    if (k == 0)
        return rr_error_set(c->err, RR_ERR_PARSE, "%s:%ld:%ld: invalid JSON at the end of the line: %s", c->file, line,
                            col, why);
    return rr_error_set(c->err, RR_ERR_PARSE, "%s:%ld:%ld: invalid JSON near '%s': %s", c->file, line, col, near, why);
}

/* ---- overrides ---- */

/* One step of an override path: a key, or an array index. */
typedef struct ov_step {
    int is_index;
    size_t index;
    char key[SP_PATH_MAX];
} ov_step;

/* Reads the next step of spec at *pos ("a.b[2].c"). Returns 1 on a step, 0 at
 * the end, -1 on a malformed path (message in why). */
static int ov_next(const char *spec, size_t *pos, ov_step *st, const char **why)
{
    size_t i = *pos;
    if (spec[i] == '\0')
        return 0;
    if (i > 0 && spec[i] == '.')
        i++;
    if (spec[i] == '[') {
        i++;
        if (!isdigit((unsigned char)spec[i])) {
            *why = "an array index must be a number in brackets, e.g. objects[2]";
            return -1;
        }
        size_t v = 0;
        while (isdigit((unsigned char)spec[i])) {
            if (v > (SIZE_MAX - 9) / 10) {
                *why = "the array index is too large";
                return -1;
            }
            v = v * 10 + (size_t)(spec[i++] - '0');
        }
        if (spec[i] != ']') {
            *why = "missing ']' after the array index";
            return -1;
        }
        i++;
        if (spec[i] != '\0' && spec[i] != '.' && spec[i] != '[') {
            *why = "expected '.' or '[' after ']'";
            return -1;
        }
        st->is_index = 1;
        st->index = v;
        *pos = i;
        return 1;
    }
    size_t k = 0;
    while (spec[i] != '\0' && spec[i] != '.' && spec[i] != '[') {
        if (spec[i] == ']') {
            *why = "unexpected ']'";
            return -1;
        }
        if (k + 1 >= sizeof st->key) {
            *why = "a key is too long";
            return -1;
        }
        st->key[k++] = spec[i++];
    }
    st->key[k] = '\0';
    if (k == 0) {
        *why = "empty key (two dots in a row, or a dot at the start or end)";
        return -1;
    }
    st->is_index = 0;
    *pos = i;
    return 1;
}

static rr_status ov_fail(const sp_ctx *c, const char *ov, const char *fmt, ...)
{
    char what[RR_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return rr_error_set(c->err, RR_ERR_INVALID, "--set '%s': %s", ov, what);
}

static rr_status apply_override(const sp_ctx *c, cJSON *root, const char *ov)
{
    const char *eq = strchr(ov, '=');
    if (!eq)
        return ov_fail(c, ov, "expected KEY=VALUE, e.g. render.spp=64");
    size_t plen = (size_t)(eq - ov);
    if (plen == 0)
        return ov_fail(c, ov, "the key before '=' is empty");
    if (plen >= SP_PATH_MAX)
        return ov_fail(c, ov, "the key is too long");
    char spec[SP_PATH_MAX];
    memcpy(spec, ov, plen);
    spec[plen] = '\0';
    if (spec[0] == '[' || spec[0] == '.')
        return ov_fail(c, ov, "the key must start with a top-level name, e.g. render.spp");

    /* The value is JSON when it parses as JSON (numbers, arrays, true, "quoted"),
     * otherwise the literal text: --set objects[2].material=red needs no quotes. */
    const char *vtext = eq + 1, *syntax = NULL;
    cJSON *value = sp_json_locate(vtext, &syntax) ? NULL : cJSON_ParseWithOpts(vtext, NULL, 1);
    if (!value)
        value = cJSON_CreateString(vtext);
    if (!value)
        return rr_error_set(c->err, RR_ERR_NOMEM, "--set '%s': out of memory", ov);

    cJSON *cur = root;
    char walked[SP_PATH_MAX] = "";
    size_t pos = 0;
    ov_step st, next;
    const char *why = NULL;
    int r = ov_next(spec, &pos, &st, &why);
    for (;;) {
        if (r < 0) {
            cJSON_Delete(value);
            return ov_fail(c, ov, "%s", why);
        }
        int rn = ov_next(spec, &pos, &next, &why);
        if (rn < 0) {
            cJSON_Delete(value);
            return ov_fail(c, ov, "%s", why);
        }
        int last = rn == 0;
        const char *here = walked[0] ? walked : "the scene";
        if (st.is_index) {
            if (!cJSON_IsArray(cur)) {
                cJSON_Delete(value);
                return ov_fail(c, ov, "%s is not an array", here);
            }
            int n = cJSON_GetArraySize(cur);
            if (st.index >= (size_t)n) {
                cJSON_Delete(value);
                return ov_fail(c, ov, "index %zu is out of range: %s has %d item%s", st.index, here, n,
                               n == 1 ? "" : "s");
            }
            if (last) {
                if (!cJSON_ReplaceItemInArray(cur, (int)st.index, value)) {
                    cJSON_Delete(value);
                    return rr_error_set(c->err, RR_ERR_NOMEM, "--set '%s': out of memory", ov);
                }
                return RR_OK;
            }
            cur = cJSON_GetArrayItem(cur, (int)st.index);
            char tmp[SP_PATH_MAX];
            sp_idx(tmp, walked, st.index);
            memcpy(walked, tmp, sizeof walked);
        } else {
            if (!cJSON_IsObject(cur)) {
                cJSON_Delete(value);
                return ov_fail(c, ov, "%s is not an object, it has no key '%s'", here, st.key);
            }
            cJSON *child = cJSON_GetObjectItemCaseSensitive(cur, st.key);
            if (last) {
                /* ReplaceItemInObject (not ...ViaPointer) names the new item
                 * with the key; an unnamed item would end lookups in cJSON. */
                cJSON_bool ok = child ? cJSON_ReplaceItemInObjectCaseSensitive(cur, st.key, value)
                                      : cJSON_AddItemToObject(cur, st.key, value);
                if (!ok) {
                    cJSON_Delete(value);
                    return rr_error_set(c->err, RR_ERR_NOMEM, "--set '%s': out of memory", ov);
                }
                return RR_OK;
            }
            if (!child) {
                /* A missing object on the way is created, so that --set render.spp=4
                 * works on a file without "render". A missing array cannot be: its
                 * indices would not exist. */
                if (next.is_index) {
                    cJSON_Delete(value);
                    return ov_fail(c, ov, "%s%s%s does not exist, so it has no index %zu", walked,
                                   walked[0] ? "." : "", st.key, next.index);
                }
                child = cJSON_AddObjectToObject(cur, st.key);
                if (!child) {
                    cJSON_Delete(value);
                    return rr_error_set(c->err, RR_ERR_NOMEM, "--set '%s': out of memory", ov);
                }
            }
            cur = child;
            char tmp[SP_PATH_MAX];
            sp_key(tmp, walked, st.key);
            memcpy(walked, tmp, sizeof walked);
        }
        st = next;
        r = rn;
    }
}

rr_status sp_apply_overrides(const sp_ctx *c, cJSON *root)
{
    if (!c->opts || c->opts->noverrides == 0)
        return RR_OK;
    for (size_t i = 0; i < c->opts->noverrides; i++) {
        const char *ov = c->opts->overrides ? c->opts->overrides[i] : NULL;
        if (!ov)
            return rr_error_set(c->err, RR_ERR_INVALID, "--set: override %zu is missing", i);
        rr_status st = apply_override(c, root, ov);
        if (st != RR_OK)
            return st;
    }
    return RR_OK;
}

/* ---- structure checks ---- */

rr_status sp_check_object(const sp_ctx *c, const cJSON *v, const char *path, const char *const *allowed)
{
    char got[96];
    if (!cJSON_IsObject(v))
        return sp_fail(c, RR_ERR_INVALID, path, "expected an object (got %s)", sp_describe(v, got, sizeof got));
    for (const cJSON *it = v->child; it; it = it->next) {
        int ok = 0;
        for (size_t i = 0; allowed[i]; i++)
            if (strcmp(it->string, allowed[i]) == 0)
                ok = 1;
        if (!ok) {
            char list[512] = "";
            size_t len = 0;
            for (size_t i = 0; allowed[i] && len < sizeof list; i++)
                len += (size_t)snprintf(list + len, sizeof list - len, "%s%s", i ? ", " : "", allowed[i]);
            return sp_fail(c, RR_ERR_INVALID, path, "unknown key '%s' (allowed: %s)", it->string, list);
        }
        for (const cJSON *b = v->child; b != it; b = b->next)
            if (strcmp(b->string, it->string) == 0)
                return sp_fail(c, RR_ERR_INVALID, path, "key '%s' appears twice", it->string);
    }
    return RR_OK;
}

const cJSON *sp_get(const cJSON *obj, const char *key) { return cJSON_GetObjectItemCaseSensitive(obj, key); }

rr_status sp_missing(const sp_ctx *c, const char *path, const char *key, const char *expected)
{
    char p[SP_PATH_MAX];
    sp_key(p, path, key);
    return sp_fail(c, RR_ERR_INVALID, p, "missing (expected %s)", expected);
}

rr_status sp_array(const sp_ctx *c, const cJSON *v, const char *path, int n, const char *expected)
{
    char got[96];
    if (!cJSON_IsArray(v) || (n > 0 && cJSON_GetArraySize(v) != n) || (n == 0 && cJSON_GetArraySize(v) < 1))
        return sp_fail(c, RR_ERR_INVALID, path, "expected %s (got %s)", expected, sp_describe(v, got, sizeof got));
    return RR_OK;
}

/* ---- typed values ---- */

rr_status sp_number_item(const sp_ctx *c, const cJSON *v, const char *path, double *out)
{
    char got[96];
    if (!cJSON_IsNumber(v))
        return sp_fail(c, RR_ERR_INVALID, path, "expected a number (got %s)", sp_describe(v, got, sizeof got));
    /* JSON has no NaN or infinity, but a literal like 1e999 overflows to one. */
    if (!isfinite(v->valuedouble))
        return sp_fail(c, RR_ERR_INVALID, path, "the number is out of range (it overflows a double to %s)",
                       v->valuedouble > 0 ? "infinity" : v->valuedouble < 0 ? "-infinity" : "NaN");
    *out = v->valuedouble;
    return RR_OK;
}

rr_status sp_number(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need,
                    double *out)
{
    const cJSON *v = sp_get(obj, key);
    if (!v)
        return need == SP_REQUIRED ? sp_missing(c, path, key, "a number") : RR_OK;
    char p[SP_PATH_MAX];
    sp_key(p, path, key);
    return sp_number_item(c, v, p, out);
}

/* "[lo, hi]", ">= lo", "<= hi" or "" for the range part of messages. */
static const char *range_text(double lo, double hi, char *buf, size_t n)
{
    if (isfinite(lo) && isfinite(hi))
        snprintf(buf, n, "in [%.16g, %.16g]", lo, hi);
    else if (isfinite(lo))
        snprintf(buf, n, ">= %.16g", lo);
    else if (isfinite(hi))
        snprintf(buf, n, "<= %.16g", hi);
    else
        snprintf(buf, n, "finite");
    return buf;
}

rr_status sp_number_range(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need,
                          double lo, double hi, double *out)
{
    double v = *out;
    const cJSON *item = sp_get(obj, key);
    if (!item)
        return need == SP_REQUIRED ? sp_missing(c, path, key, "a number") : RR_OK;
    char p[SP_PATH_MAX], rt[64];
    sp_key(p, path, key);
    rr_status st = sp_number_item(c, item, p, &v);
    if (st != RR_OK)
        return st;
    if (!(v >= lo && v <= hi))
        return sp_fail(c, RR_ERR_INVALID, p, "must be %s (got %g)", range_text(lo, hi, rt, sizeof rt), v);
    *out = v;
    return RR_OK;
}

rr_status sp_int_item(const sp_ctx *c, const cJSON *v, const char *path, double lo, double hi, double *out)
{
    char got[96], rt[64];
    if (!cJSON_IsNumber(v))
        return sp_fail(c, RR_ERR_INVALID, path, "expected an integer (got %s)", sp_describe(v, got, sizeof got));
    double d = v->valuedouble;
    if (!isfinite(d) || fabs(d) > SP_INT_EXACT)
        return sp_fail(c, RR_ERR_INVALID, path, "expected an integer %s (got a number too large to be exact)",
                       range_text(lo, hi, rt, sizeof rt));
    if (d != floor(d))
        return sp_fail(c, RR_ERR_INVALID, path, "expected an integer (got %g)", d);
    if (d < lo || d > hi)
        return sp_fail(c, RR_ERR_INVALID, path, "must be an integer %s (got %.0f)", range_text(lo, hi, rt, sizeof rt),
                       d);
    *out = d;
    return RR_OK;
}

rr_status sp_int(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need, double lo,
                 double hi, double *out)
{
    const cJSON *v = sp_get(obj, key);
    if (!v)
        return need == SP_REQUIRED ? sp_missing(c, path, key, "an integer") : RR_OK;
    char p[SP_PATH_MAX];
    sp_key(p, path, key);
    return sp_int_item(c, v, p, lo, hi, out);
}

rr_status sp_bool(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need, int *out)
{
    const cJSON *v = sp_get(obj, key);
    if (!v)
        return need == SP_REQUIRED ? sp_missing(c, path, key, "true or false") : RR_OK;
    char p[SP_PATH_MAX], got[96];
    sp_key(p, path, key);
    if (!cJSON_IsBool(v))
        return sp_fail(c, RR_ERR_INVALID, p, "expected true or false (got %s)", sp_describe(v, got, sizeof got));
    *out = cJSON_IsTrue(v) ? 1 : 0;
    return RR_OK;
}

rr_status sp_string(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need,
                    int nonempty, char *out, size_t out_size)
{
    const cJSON *v = sp_get(obj, key);
    if (!v)
        return need == SP_REQUIRED ? sp_missing(c, path, key, "a string") : RR_OK;
    char p[SP_PATH_MAX], got[96];
    sp_key(p, path, key);
    if (!cJSON_IsString(v))
        return sp_fail(c, RR_ERR_INVALID, p, "expected a string (got %s)", sp_describe(v, got, sizeof got));
    size_t n = strlen(v->valuestring);
    if (nonempty && n == 0)
        return sp_fail(c, RR_ERR_INVALID, p, "expected a non-empty string");
    if (n >= out_size)
        return sp_fail(c, RR_ERR_INVALID, p, "the string is too long (%zu bytes, at most %zu)", n, out_size - 1);
    memcpy(out, v->valuestring, n + 1);
    return RR_OK;
}

rr_status sp_vec3_item(const sp_ctx *c, const cJSON *v, const char *path, rr_vec3 *out)
{
    rr_status st = sp_array(c, v, path, 3, "an array of 3 numbers [x, y, z]");
    if (st != RR_OK)
        return st;
    double xyz[3];
    for (int i = 0; i < 3; i++) {
        char p[SP_PATH_MAX];
        sp_idx(p, path, (size_t)i);
        st = sp_number_item(c, cJSON_GetArrayItem(v, i), p, &xyz[i]);
        if (st != RR_OK)
            return st;
    }
    *out = rr_v3(xyz[0], xyz[1], xyz[2]);
    return RR_OK;
}

rr_status sp_vec3(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need,
                  rr_vec3 *out)
{
    const cJSON *v = sp_get(obj, key);
    if (!v)
        return need == SP_REQUIRED ? sp_missing(c, path, key, "an array of 3 numbers [x, y, z]") : RR_OK;
    char p[SP_PATH_MAX];
    sp_key(p, path, key);
    return sp_vec3_item(c, v, p, out);
}

rr_status sp_color(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need, double lo,
                   double hi, rr_rgb *out)
{
    const cJSON *v = sp_get(obj, key);
    if (!v)
        return need == SP_REQUIRED ? sp_missing(c, path, key, "a number or an array of 3 numbers [r, g, b]")
                                   : RR_OK;
    char p[SP_PATH_MAX], got[96], rt[64];
    sp_key(p, path, key);
    double ch[3] = {0, 0, 0};
    if (cJSON_IsNumber(v)) {
        rr_status st = sp_number_item(c, v, p, &ch[0]);
        if (st != RR_OK)
            return st;
        if (!(ch[0] >= lo && ch[0] <= hi))
            return sp_fail(c, RR_ERR_INVALID, p, "must be %s (got %g)", range_text(lo, hi, rt, sizeof rt), ch[0]);
        ch[1] = ch[2] = ch[0];
    } else if (cJSON_IsArray(v) && cJSON_GetArraySize(v) == 3) {
        for (int i = 0; i < 3; i++) {
            char pi[SP_PATH_MAX];
            sp_idx(pi, p, (size_t)i);
            rr_status st = sp_number_item(c, cJSON_GetArrayItem(v, i), pi, &ch[i]);
            if (st != RR_OK)
                return st;
            if (!(ch[i] >= lo && ch[i] <= hi))
                return sp_fail(c, RR_ERR_INVALID, pi, "must be %s (got %g)", range_text(lo, hi, rt, sizeof rt),
                               ch[i]);
        }
    } else {
        return sp_fail(c, RR_ERR_INVALID, p, "expected a number or an array of 3 numbers [r, g, b] (got %s)",
                       sp_describe(v, got, sizeof got));
    }
    *out = rr_rgb_make(ch[0], ch[1], ch[2]);
    return RR_OK;
}
