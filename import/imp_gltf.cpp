/* imp_gltf.cpp - imp__load_gltf: .gltf and .glb files through tinygltf 2.7.0
 * (see imp.h for the contract, notes/import.md for the material mapping).
 *
 * What is read:
 *  - The default scene's node trees (scene 0 when the file names none; every
 *    root node when it has no scenes), with node transforms accumulated in
 *    double. Each triangle primitive (TRIANGLES, TRIANGLE_STRIP,
 *    TRIANGLE_FAN) of a node's mesh becomes one imp_mesh; points and lines
 *    are counted in dropped_prims. A transform with a negative determinant
 *    has its triangles' winding reversed, so counter-clockwise stays front.
 *  - Every material, in file order (imp_material i is glTF material i), plus
 *    one "default" material at the end only if a primitive has none.
 *  - KHR_lights_punctual point and directional lights placed by nodes; spot
 *    lights (and unknown kinds) are counted in dropped_lights.
 * Skins, morph targets, animations and cameras are ignored (cameras are
 * counted): meshes are taken in their bind pose.
 *
 * The file is untrusted: every index into the model's arrays, every accessor
 * (count x stride within its bufferView, bufferView within its buffer), every
 * vertex index and every number that reaches radray is checked here, because
 * tinygltf 2.7.0 checks almost none of it. tinygltf's image decoding is
 * replaced by a loader that only keeps the encoded bytes (after checking the
 * bufferView, which tinygltf does not); base-colour images are decoded later,
 * once each, and an image that cannot be decoded is dropped with a note
 * instead of failing the whole file.
 *
 * Materials (and their texture means) are mapped in imp_gltf_material.cpp;
 * imp_gltf_internal.hpp holds what the two files share.
 *
 * No C++ exception leaves this file: imp__load_gltf catches everything.
 */
#include <tiny_gltf.h>

#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include "imp_gltf_internal.hpp"

namespace imp_gltf {

rr_status gltf_fail(const gltf_ctx &c, rr_status code, const char *fmt, ...)
{
    char buf[RR_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return rr_error_set(c.err, code, "%s: %s", c.path, buf);
}

/* A string from the file, fit for a one-line message: at most max bytes (cut
 * at a UTF-8 boundary, "..." appended), control characters as '?'. */
std::string gltf_clip(const std::string &s, size_t max)
{
    std::string out = s.substr(0, s.size() > max ? max : s.size());
    if (out.size() < s.size()) {
        while (!out.empty() && (static_cast<unsigned char>(s[out.size()]) & 0xC0) == 0x80)
            out.pop_back();
        out += "...";
    }
    for (char &ch : out)
        if (static_cast<unsigned char>(ch) < 0x20 || ch == 0x7F)
            ch = '?';
    return out;
}

/* "mesh 'Cube' (meshes[2])", or "meshes[2]" when it has no name. */
std::string gltf_label(const char *kind, const std::string &name, const char *array, size_t i)
{
    std::string where = std::string(array) + "[" + std::to_string(i) + "]";
    if (name.empty())
        return where;
    return std::string(kind) + " '" + gltf_clip(name, IMP_NAME_MAX) + "' (" + where + ")";
}

/* v must be finite and in [lo, hi] (hi < 0: no upper bound). */
rr_status gltf_check_factor(const gltf_ctx &c, const std::string &where, const std::string &what, double v, double lo,
                            double hi)
{
    if (!std::isfinite(v))
        return gltf_fail(c, RR_ERR_INVALID, "%s: %s is not a finite number", where.c_str(), what.c_str());
    if (v < lo || (hi >= 0 && v > hi)) {
        if (hi >= 0)
            return gltf_fail(c, RR_ERR_INVALID, "%s: %s is %g: must be in [%g, %g]", where.c_str(), what.c_str(), v, lo,
                             hi);
        return gltf_fail(c, RR_ERR_INVALID, "%s: %s is %g: must be >= %g", where.c_str(), what.c_str(), v, lo);
    }
    return RR_OK;
}

rr_status gltf_check_array(const gltf_ctx &c, const std::string &where, const std::string &what,
                           const std::vector<double> &v, size_t n, double hi)
{
    if (v.size() != n)
        return gltf_fail(c, RR_ERR_INVALID, "%s: %s has %zu values: must have %zu", where.c_str(), what.c_str(),
                         v.size(), n);
    for (size_t k = 0; k < n; k++) {
        rr_status s = gltf_check_factor(c, where, what + "[" + std::to_string(k) + "]", v[k], 0.0, hi);
        if (s != RR_OK)
            return s;
    }
    return RR_OK;
}

} // namespace imp_gltf

using namespace imp_gltf;

namespace {

const int GLTF_MAX_DEPTH = 64;       /* node tree */
const int GLTF_MAX_JSON_DEPTH = 512; /* arrays and objects in the JSON */
const char *const GLTF_SUPPORTED[] = {"KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_unlit",
                                      "KHR_texture_transform"};

/* Column-major 4x4 (glTF's order): element (row r, column c) is a[4 * c + r]. */
struct gltf_mat4 {
    double a[16];
};

/* tinygltf's error text on one line: newlines become "; ", none trailing. */
std::string gltf_one_line(const std::string &text)
{
    std::string out;
    size_t start = 0;
    while (start < text.size()) {
        size_t end = text.find('\n', start);
        if (end == std::string::npos)
            end = text.size();
        std::string line = text.substr(start, end - start);
        while (!line.empty() && (line.back() == '\r' || line.back() == ' '))
            line.pop_back();
        if (!line.empty())
            out += (out.empty() ? "" : "; ") + line;
        start = end + 1;
    }
    return gltf_clip(out.empty() ? std::string("tinygltf failed without a message") : out, 480);
}

/* tinygltf's image callback: keeps the encoded bytes (decoded later, and only
 * for base-colour textures). tinygltf 2.7.0 passes &buffer.data[byteOffset]
 * with byteLength for an image in a bufferView without checking either
 * against the buffer, so that is checked first, before any byte is read. */
bool gltf_keep_image(tinygltf::Image *img, const int index, std::string *err, std::string *, int, int,
                     const unsigned char *bytes, int size, void *user)
{
    const tinygltf::Model *g = static_cast<const tinygltf::Model *>(user);
    if (img->bufferView >= 0) {
        /* tinygltf checked both indices before calling */
        const tinygltf::BufferView &bv = g->bufferViews[static_cast<size_t>(img->bufferView)];
        size_t have = g->buffers[static_cast<size_t>(bv.buffer)].data.size();
        if (bv.byteOffset > have || bv.byteLength > have - bv.byteOffset || size < 0) {
            *err += "images[" + std::to_string(index) + "]: bufferView " + std::to_string(img->bufferView) +
                    " lies outside its buffer\n";
            return false;
        }
    }
    if (bytes && size > 0) {
        img->image.assign(bytes, bytes + size);
        img->as_is = true;
    }
    return true;
}

/* Deepest nesting of [ and { in JSON text, strings skipped. */
size_t gltf_json_depth(const unsigned char *p, size_t n)
{
    size_t depth = 0, deepest = 0;
    bool in_string = false;
    for (size_t i = 0; i < n; i++) {
        unsigned char ch = p[i];
        if (in_string) {
            if (ch == '\\')
                i++;
            else if (ch == '"')
                in_string = false;
        } else if (ch == '"') {
            in_string = true;
        } else if (ch == '[' || ch == '{') {
            deepest = ++depth > deepest ? depth : deepest;
        } else if ((ch == ']' || ch == '}') && depth > 0) {
            depth--;
        }
    }
    return deepest;
}

/* The file's JSON: all of a .gltf, the first chunk of a .glb (as much of it
 * as the file holds; a malformed header is left to tinygltf). */
size_t gltf_json_depth_of_file(const unsigned char *d, size_t n, int binary)
{
    if (!binary)
        return gltf_json_depth(d, n);
    if (n < 20)
        return 0;
    uint32_t len;
    memcpy(&len, d + 12, sizeof len);
    return gltf_json_depth(d + 20, len < n - 20 ? len : n - 20);
}

/* tinygltf's error text as an rr_status: IO only when a referenced file is
 * not there or cannot be read. */
rr_status gltf_load_status(const std::string &terr)
{
    if (terr.find("File is empty") != std::string::npos || terr.find("'uri' is missing") != std::string::npos)
        return RR_ERR_PARSE;
    if (terr.find("File not found") != std::string::npos || terr.find("File open error") != std::string::npos ||
        terr.find("File read error") != std::string::npos)
        return RR_ERR_IO;
    return RR_ERR_PARSE;
}

/* The file is read here rather than by tinygltf's LoadBinaryFromFile /
 * LoadASCIIFromFile: rr_file_read_all refuses FIFOs and devices (tinygltf
 * would block on a FIFO), and the JSON's nesting is bounded first, because
 * tinygltf 2.7.0 parses extras and extensions recursively and overflows the
 * stack at some 30000 levels. Referenced files are looked for where
 * tinygltf's own file loaders look: next to the file, then in the current
 * folder. */
rr_status gltf_read(const char *path, int binary, tinygltf::Model *g, rr_error *err)
{
    char *raw = nullptr;
    size_t size = 0;
    rr_status s = rr_file_read_all(path, &raw, &size, err);
    if (s != RR_OK)
        return s;
    std::unique_ptr<char, void (*)(void *)> hold(raw, free);
    const unsigned char *bytes = reinterpret_cast<const unsigned char *>(raw);
    if (size == 0)
        return rr_error_set(err, RR_ERR_PARSE, "%s: the file is empty", path);
    if (size > UINT32_MAX)
        return rr_error_set(err, RR_ERR_LIMIT, "%s: the file is larger than 4 GiB, more than tinygltf reads", path);
    if (gltf_json_depth_of_file(bytes, size, binary) > GLTF_MAX_JSON_DEPTH)
        return rr_error_set(err, RR_ERR_PARSE, "%s: the JSON nests arrays and objects more than %d deep", path,
                            GLTF_MAX_JSON_DEPTH);
    std::string p(path);
    size_t slash = p.find_last_of('/');
    std::string base = slash == std::string::npos ? std::string() : p.substr(0, slash);
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(gltf_keep_image, g);
    std::string terr, twarn;
    bool ok;
    try {
        unsigned n = static_cast<unsigned>(size);
        ok = binary ? loader.LoadBinaryFromMemory(g, &terr, &twarn, bytes, n, base)
                    : loader.LoadASCIIFromString(g, &terr, &twarn, raw, n, base);
    } catch (const std::bad_alloc &) {
        throw;
    } catch (const std::exception &e) {
        /* tinygltf's own std::vector::at on malformed input, for one */
        return rr_error_set(err, RR_ERR_PARSE, "%s: tinygltf failed: %s", path, gltf_clip(e.what(), 200).c_str());
    }
    if (ok)
        return RR_OK;
    return rr_error_set(err, gltf_load_status(terr), "%s: %s", path, gltf_one_line(terr).c_str());
}

rr_status gltf_check_extensions(const gltf_ctx &c)
{
    for (const std::string &ext : c.g.extensionsRequired) {
        bool known = false;
        for (const char *s : GLTF_SUPPORTED)
            known = known || ext == s;
        if (known)
            continue;
        std::string list;
        for (const char *s : GLTF_SUPPORTED)
            list += (list.empty() ? "" : ", ") + std::string(s);
        return gltf_fail(c, RR_ERR_INVALID,
                         "the file requires extension '%s', which radray does not support (supported: %s)",
                         gltf_clip(ext, 100).c_str(), list.c_str());
    }
    return RR_OK;
}

/* ---- transforms --------------------------------------------------------- */

gltf_mat4 gltf_identity()
{
    gltf_mat4 r = {{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}};
    return r;
}

gltf_mat4 gltf_mul(const gltf_mat4 &x, const gltf_mat4 &y)
{
    gltf_mat4 r;
    for (int col = 0; col < 4; col++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += x.a[4 * k + row] * y.a[4 * col + k];
            r.a[4 * col + row] = s;
        }
    return r;
}

rr_vec3 gltf_column(const gltf_mat4 &x, int col) { return rr_v3(x.a[4 * col], x.a[4 * col + 1], x.a[4 * col + 2]); }

/* T * R * S; rotation is a quaternion (x, y, z, w), normalised here. */
gltf_mat4 gltf_trs(const double t[3], const double q[4], const double s[3])
{
    double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double x = q[0] / n, y = q[1] / n, z = q[2] / n, w = q[3] / n;
    double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                      {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                      {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    gltf_mat4 m = gltf_identity();
    for (int col = 0; col < 3; col++) {
        for (int row = 0; row < 3; row++)
            m.a[4 * col + row] = r[row][col] * s[col];
        m.a[12 + col] = t[col];
    }
    return m;
}

/* The node's own transform: matrix, or translation / rotation / scale. */
rr_status gltf_local(const gltf_ctx &c, const tinygltf::Node &n, const std::string &where, gltf_mat4 *out)
{
    struct field {
        const char *name;
        const std::vector<double> *v;
        size_t n;
    } fields[] = {{"matrix", &n.matrix, 16},
                  {"translation", &n.translation, 3},
                  {"rotation", &n.rotation, 4},
                  {"scale", &n.scale, 3}};
    for (const field &f : fields) {
        if (!f.v->empty() && f.v->size() != f.n)
            return gltf_fail(c, RR_ERR_INVALID, "%s: %s has %zu values: must have %zu", where.c_str(), f.name,
                             f.v->size(), f.n);
        for (size_t k = 0; k < f.v->size(); k++)
            if (!std::isfinite((*f.v)[k]))
                return gltf_fail(c, RR_ERR_INVALID, "%s: %s[%zu] is not a finite number", where.c_str(), f.name, k);
    }
    if (!n.matrix.empty()) {
        for (int k = 0; k < 16; k++)
            out->a[k] = n.matrix[static_cast<size_t>(k)];
        return RR_OK;
    }
    double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    for (size_t k = 0; k < n.translation.size(); k++)
        t[k] = n.translation[k];
    for (size_t k = 0; k < n.rotation.size(); k++)
        q[k] = n.rotation[k];
    for (size_t k = 0; k < n.scale.size(); k++)
        s[k] = n.scale[k];
    if (!(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] > 1e-12))
        return gltf_fail(c, RR_ERR_INVALID, "%s: rotation is (%g, %g, %g, %g): not a unit quaternion", where.c_str(),
                         q[0], q[1], q[2], q[3]);
    *out = gltf_trs(t, q, s);
    return RR_OK;
}

/* ---- accessors ---------------------------------------------------------- */

/* An accessor checked against its bufferView and buffer: element i starts at
 * base + i * stride and has elem bytes. */
struct gltf_view {
    const unsigned char *base = nullptr;
    size_t stride = 0, count = 0;
};

size_t gltf_component_size(int type)
{
    switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    case TINYGLTF_COMPONENT_TYPE_DOUBLE: return 8;
    default: return 0;
    }
}

/* Bounds only: the caller has checked the types (so elem > 0). */
rr_status gltf_view_bounds(const gltf_ctx &c, const std::string &where, const tinygltf::Accessor &a, size_t elem,
                           gltf_view *out)
{
    if (a.bufferView < 0 || static_cast<size_t>(a.bufferView) >= c.g.bufferViews.size())
        return gltf_fail(c, RR_ERR_INVALID, "%s: bufferView is %d: the file has %zu bufferViews", where.c_str(),
                         a.bufferView, c.g.bufferViews.size());
    const tinygltf::BufferView &bv = c.g.bufferViews[static_cast<size_t>(a.bufferView)];
    if (bv.buffer < 0 || static_cast<size_t>(bv.buffer) >= c.g.buffers.size())
        return gltf_fail(c, RR_ERR_INVALID, "%s: bufferViews[%d].buffer is %d: the file has %zu buffers", where.c_str(),
                         a.bufferView, bv.buffer, c.g.buffers.size());
    const std::vector<unsigned char> &data = c.g.buffers[static_cast<size_t>(bv.buffer)].data;
    if (bv.byteOffset > data.size() || bv.byteLength > data.size() - bv.byteOffset)
        return gltf_fail(c, RR_ERR_INVALID,
                         "%s: bufferViews[%d] (bytes %zu + %zu) lies outside buffers[%d] (%zu bytes)", where.c_str(),
                         a.bufferView, bv.byteOffset, bv.byteLength, bv.buffer, data.size());
    size_t stride = bv.byteStride ? bv.byteStride : elem;
    if (stride < elem)
        return gltf_fail(c, RR_ERR_INVALID, "%s: bufferViews[%d].byteStride is %zu, less than an element (%zu bytes)",
                         where.c_str(), a.bufferView, stride, elem);
    size_t room = bv.byteLength;
    bool fits = a.count == 0 || (a.byteOffset <= room && elem <= room - a.byteOffset &&
                                 a.count - 1 <= (room - a.byteOffset - elem) / stride);
    if (!fits)
        return gltf_fail(
            c, RR_ERR_INVALID,
            "%s: %zu elements of %zu bytes, %zu apart, from byte %zu do not fit in bufferViews[%d] (%zu bytes)",
            where.c_str(), a.count, elem, stride, a.byteOffset, a.bufferView, room);
    out->base = a.count ? data.data() + bv.byteOffset + a.byteOffset : nullptr;
    out->stride = stride;
    out->count = a.count;
    return RR_OK;
}

/* Opens accessor index as a FLOAT VEC3 (POSITION, NORMAL). */
rr_status gltf_open_vec3(const gltf_ctx &c, const std::string &prim, const char *attr, int index, gltf_view *out)
{
    if (index < 0 || static_cast<size_t>(index) >= c.g.accessors.size())
        return gltf_fail(c, RR_ERR_INVALID, "%s: %s is accessor %d: the file has %zu accessors", prim.c_str(), attr,
                         index, c.g.accessors.size());
    const tinygltf::Accessor &a = c.g.accessors[static_cast<size_t>(index)];
    std::string where = prim + ": " + attr + " (accessors[" + std::to_string(index) + "])";
    if (a.sparse.isSparse)
        return gltf_fail(c, RR_ERR_INVALID, "%s: sparse accessors are not supported", where.c_str());
    if (a.type != TINYGLTF_TYPE_VEC3 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || a.normalized)
        return gltf_fail(c, RR_ERR_INVALID, "%s: must be a VEC3 of FLOAT, not normalized (type %d, componentType %d%s)",
                         where.c_str(), a.type, a.componentType, a.normalized ? ", normalized" : "");
    return gltf_view_bounds(c, where, a, 12, out);
}

void gltf_get_vec3(const gltf_view &v, size_t i, double out[3])
{
    float f[3];
    memcpy(f, v.base + i * v.stride, sizeof f); /* may be unaligned */
    out[0] = f[0], out[1] = f[1], out[2] = f[2];
}

/* The primitive's vertex indices into c.idx: its indices accessor, or
 * 0 .. nverts-1 without one. Each is checked against nverts. */
rr_status gltf_read_indices(gltf_ctx &c, const std::string &prim, int index, size_t nverts)
{
    if (index == -1) {
        c.idx.resize(nverts);
        for (size_t i = 0; i < nverts; i++)
            c.idx[i] = static_cast<uint32_t>(i);
        return RR_OK;
    }
    if (index < 0 || static_cast<size_t>(index) >= c.g.accessors.size())
        return gltf_fail(c, RR_ERR_INVALID, "%s: indices is accessor %d: the file has %zu accessors", prim.c_str(),
                         index, c.g.accessors.size());
    const tinygltf::Accessor &a = c.g.accessors[static_cast<size_t>(index)];
    std::string where = prim + ": indices (accessors[" + std::to_string(index) + "])";
    size_t size = gltf_component_size(a.componentType);
    if (a.sparse.isSparse)
        return gltf_fail(c, RR_ERR_INVALID, "%s: sparse accessors are not supported", where.c_str());
    if (a.type != TINYGLTF_TYPE_SCALAR || a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT || size == 0 || size > 4 ||
        a.componentType == TINYGLTF_COMPONENT_TYPE_BYTE || a.componentType == TINYGLTF_COMPONENT_TYPE_SHORT ||
        a.componentType == TINYGLTF_COMPONENT_TYPE_INT)
        return gltf_fail(
            c, RR_ERR_INVALID,
            "%s: must be a SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT (type %d, componentType %d)",
            where.c_str(), a.type, a.componentType);
    gltf_view v;
    rr_status s = gltf_view_bounds(c, where, a, size, &v);
    if (s != RR_OK)
        return s;
    c.idx.resize(v.count);
    for (size_t i = 0; i < v.count; i++) {
        const unsigned char *p = v.base + i * v.stride;
        uint32_t x;
        if (size == 1) {
            x = p[0];
        } else if (size == 2) {
            uint16_t h;
            memcpy(&h, p, sizeof h);
            x = h;
        } else {
            memcpy(&x, p, sizeof x);
        }
        if (x >= nverts)
            return gltf_fail(c, RR_ERR_INVALID, "%s: index %zu is %u, but POSITION has %zu vertices", where.c_str(), i,
                             (unsigned)x, nverts);
        c.idx[i] = x;
    }
    return RR_OK;
}

/* ---- primitives --------------------------------------------------------- */

/* c.idx assembled into c.tris by mode, winding reversed when flip. */
rr_status gltf_assemble(gltf_ctx &c, const std::string &prim, int mode, bool flip)
{
    const std::vector<uint32_t> &v = c.idx;
    size_t n = v.size();
    if (mode == TINYGLTF_MODE_TRIANGLES) {
        if (n % 3)
            return gltf_fail(c, RR_ERR_INVALID, "%s: TRIANGLES with %zu indices, not a multiple of 3", prim.c_str(), n);
        c.tris.swap(c.idx); /* already a triangle list */
    } else {
        size_t ntris = n >= 3 ? n - 2 : 0;
        c.tris.resize(3 * ntris);
        uint32_t *t = c.tris.data();
        for (size_t i = 0; i < ntris; i++, t += 3) {
            if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) /* glTF: {v[i], v[i + 1 + i%2], v[i + 2 - i%2]} */
                t[0] = v[i], t[1] = v[i + 1 + i % 2], t[2] = v[i + 2 - i % 2];
            else
                t[0] = v[0], t[1] = v[i + 1], t[2] = v[i + 2];
        }
    }
    if (flip)
        for (size_t i = 0; i < c.tris.size(); i += 3) {
            uint32_t tmp = c.tris[i + 1];
            c.tris[i + 1] = c.tris[i + 2];
            c.tris[i + 2] = tmp;
        }
    return RR_OK;
}

/* POSITION through the world matrix into c.pos. */
rr_status gltf_read_positions(gltf_ctx &c, const std::string &prim, const gltf_view &v, const gltf_mat4 &w)
{
    c.pos.resize(3 * v.count);
    for (size_t i = 0; i < v.count; i++) {
        double p[3];
        gltf_get_vec3(v, i, p);
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
            return gltf_fail(c, RR_ERR_INVALID, "%s: POSITION of vertex %zu is not finite (%g, %g, %g)", prim.c_str(),
                             i, p[0], p[1], p[2]);
        double *q = &c.pos[3 * i];
        for (int r = 0; r < 3; r++)
            q[r] = w.a[r] * p[0] + w.a[4 + r] * p[1] + w.a[8 + r] * p[2] + w.a[12 + r];
        if (!std::isfinite(q[0]) || !std::isfinite(q[1]) || !std::isfinite(q[2]))
            return gltf_fail(c, RR_ERR_INVALID, "%s: vertex %zu is not finite after the node transform", prim.c_str(),
                             i);
    }
    return RR_OK;
}

/* NORMAL through the inverse transpose into c.nrm, unit length; false (no
 * normals) for a singular transform or a normal that is zero or not finite. */
bool gltf_read_normals(gltf_ctx &c, const gltf_view &v, const gltf_mat4 &w)
{
    /* inverse transpose = cofactor / det; the cofactor's columns are the
     * crosses of the matrix's columns */
    rr_vec3 c0 = gltf_column(w, 0), c1 = gltf_column(w, 1), c2 = gltf_column(w, 2);
    rr_vec3 k0 = rr_v3_cross(c1, c2), k1 = rr_v3_cross(c2, c0), k2 = rr_v3_cross(c0, c1);
    double det = rr_v3_dot(c0, k0);
    if (!(std::fabs(det) > 0) || !std::isfinite(det))
        return false;
    double sign = det < 0 ? -1.0 : 1.0;
    c.nrm.resize(3 * v.count);
    for (size_t i = 0; i < v.count; i++) {
        double n[3];
        gltf_get_vec3(v, i, n);
        rr_vec3 t = rr_v3_scale(
            rr_v3_add(rr_v3_add(rr_v3_scale(k0, n[0]), rr_v3_scale(k1, n[1])), rr_v3_scale(k2, n[2])), sign);
        double len = rr_v3_len(t);
        if (!(len > 0) || !std::isfinite(len))
            return false;
        c.nrm[3 * i] = t.x / len, c.nrm[3 * i + 1] = t.y / len, c.nrm[3 * i + 2] = t.z / len;
    }
    return true;
}

/* The primitive's vertices, normals and triangles into c's scratch arrays. */
rr_status gltf_read_primitive(gltf_ctx &c, const std::string &prim, const tinygltf::Primitive &p, int mode,
                              const gltf_mat4 &w, bool *normals)
{
    auto pit = p.attributes.find("POSITION");
    if (pit == p.attributes.end())
        return gltf_fail(c, RR_ERR_INVALID, "%s: has no POSITION attribute", prim.c_str());
    gltf_view pv, nv;
    rr_status s = gltf_open_vec3(c, prim, "POSITION", pit->second, &pv);
    if (s == RR_OK)
        s = gltf_read_positions(c, prim, pv, w);
    if (s != RR_OK)
        return s;
    *normals = false;
    auto nit = p.attributes.find("NORMAL");
    if (nit != p.attributes.end()) {
        if ((s = gltf_open_vec3(c, prim, "NORMAL", nit->second, &nv)) != RR_OK)
            return s;
        if (nv.count != pv.count)
            return gltf_fail(c, RR_ERR_INVALID, "%s: NORMAL has %zu elements but POSITION has %zu", prim.c_str(),
                             nv.count, pv.count);
        *normals = gltf_read_normals(c, nv, w);
    }
    if ((s = gltf_read_indices(c, prim, p.indices, pv.count)) != RR_OK)
        return s;
    rr_vec3 c0 = gltf_column(w, 0), c1 = gltf_column(w, 1), c2 = gltf_column(w, 2);
    bool flip = rr_v3_dot(c0, rr_v3_cross(c1, c2)) < 0;
    return gltf_assemble(c, prim, mode, flip);
}

/* One primitive of node ni's mesh as an imp_mesh. */
rr_status gltf_add_primitive(gltf_ctx &c, size_t ni, size_t mi, size_t pi, const gltf_mat4 &w)
{
    const tinygltf::Mesh &mesh = c.g.meshes[mi];
    const tinygltf::Primitive &p = mesh.primitives[pi];
    std::string prim = gltf_label("mesh", mesh.name, "meshes", mi) + " primitive " + std::to_string(pi);
    int mode = p.mode; /* TRIANGLES when the file gives none (tinygltf's default) */
    if (mode >= TINYGLTF_MODE_POINTS && mode <= TINYGLTF_MODE_LINE_STRIP) {
        c.m->dropped_prims++;
        return RR_OK;
    }
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN)
        return gltf_fail(c, RR_ERR_INVALID, "%s: mode is %d: not a glTF primitive mode (0 to 6)", prim.c_str(), mode);
    uint32_t material = 0;
    bool normals = false;
    rr_status s = gltf_read_primitive(c, prim, p, mode, w, &normals);
    if (s != RR_OK || c.tris.empty())
        return s; /* nothing to add for a strip or fan of fewer than 3 */
    if ((s = gltf_primitive_material(c, prim, p.material, &material)) != RR_OK)
        return s;
    mesh_tri *tri = nullptr;
    rr_error merr;
    s = mesh_from_arrays(c.pos.data(), c.pos.size() / 3, c.tris.data(), c.tris.size() / 3,
                         normals ? c.nrm.data() : nullptr, &tri, &merr);
    if (s != RR_OK)
        return gltf_fail(c, s, "%s: %s", prim.c_str(), merr.msg);
    const std::string &node = c.g.nodes[ni].name;
    std::string name = node.empty() ? "nodes[" + std::to_string(ni) + "]" : node;
    if (mesh.primitives.size() > 1)
        name += "." + std::to_string(pi);
    if ((s = imp__add_mesh(c.m, name.c_str(), material, tri, c.err)) != RR_OK) /* it freed tri */
        rr_error_prefix(c.err, "%s", c.path);
    return s;
}

/* ---- lights ------------------------------------------------------------- */

rr_status gltf_check_light(const gltf_ctx &c, const tinygltf::Light &l, const std::string &where, rr_rgb *out)
{
    std::vector<double> color = l.color.empty() ? std::vector<double>{1.0, 1.0, 1.0} : l.color;
    rr_status s = gltf_check_array(c, where, "color", color, 3, -1.0);
    if (s == RR_OK)
        s = gltf_check_factor(c, where, "intensity", l.intensity, 0.0, -1.0);
    if (s != RR_OK)
        return s;
    *out = rr_rgb_scale(rr_rgb_make(color[0], color[1], color[2]), l.intensity);
    if (!rr_rgb_isfinite(*out))
        return gltf_fail(c, RR_ERR_INVALID, "%s: color x intensity is not finite", where.c_str());
    return RR_OK;
}

/* The KHR_lights_punctual light on node ni, if any, placed by w. */
rr_status gltf_add_light(gltf_ctx &c, size_t ni, const std::string &node_where, const gltf_mat4 &w)
{
    const tinygltf::ExtensionMap &ext = c.g.nodes[ni].extensions;
    auto it = ext.find("KHR_lights_punctual");
    if (it == ext.end())
        return RR_OK;
    const tinygltf::Value &v = it->second;
    if (!v.IsObject() || !v.Has("light") || !v.Get("light").IsInt())
        return gltf_fail(c, RR_ERR_INVALID, "%s: extensions.KHR_lights_punctual.light is missing or not an integer",
                         node_where.c_str());
    int li = v.Get("light").Get<int>();
    if (li < 0 || static_cast<size_t>(li) >= c.g.lights.size())
        return gltf_fail(c, RR_ERR_INVALID, "%s: extensions.KHR_lights_punctual.light is %d: the file has %zu lights",
                         node_where.c_str(), li, c.g.lights.size());
    const tinygltf::Light &l = c.g.lights[static_cast<size_t>(li)];
    if (l.type != "point" && l.type != "directional") {
        c.m->dropped_lights++; /* spot, or a kind radray does not have */
        return RR_OK;
    }
    std::string where = gltf_label("light", l.name, "extensions.KHR_lights_punctual.lights", static_cast<size_t>(li));
    rr_rgb intensity;
    rr_status s = gltf_check_light(c, l, where, &intensity);
    if (s != RR_OK)
        return s;
    rr_vec3 dir = gltf_column(w, 2); /* the light shines along the node's -Z */
    if (l.type == "directional" && !(rr_v3_len(dir) > 0 && std::isfinite(rr_v3_len(dir))))
        return gltf_fail(c, RR_ERR_INVALID, "%s: the direction given by %s is degenerate", where.c_str(),
                         node_where.c_str());
    imp_light *dst = imp__add_light(c.m);
    if (!dst)
        return gltf_fail(c, RR_ERR_NOMEM, "out of memory for %s", where.c_str());
    imp__name(dst->name, l.name.c_str(), "light", static_cast<size_t>(li));
    dst->intensity = intensity;
    if (l.type == "point") {
        dst->type = IMP_LIGHT_POINT;
        dst->position = gltf_column(w, 3);
    } else {
        dst->type = IMP_LIGHT_DIRECTIONAL;
        dst->direction = rr_v3_scale(dir, 1.0 / rr_v3_len(dir));
    }
    return RR_OK;
}

/* ---- the node trees ----------------------------------------------------- */

rr_status gltf_walk(gltf_ctx &c, size_t ni, const gltf_mat4 &parent, int depth)
{
    const tinygltf::Node &n = c.g.nodes[ni];
    std::string where = gltf_label("node", n.name, "nodes", ni);
    if (depth > GLTF_MAX_DEPTH || c.visit[ni] == 1)
        return gltf_fail(c, RR_ERR_INVALID, "%s: the node tree is more than %d deep or has a cycle", where.c_str(),
                         GLTF_MAX_DEPTH);
    if (c.visit[ni] == 2)
        return gltf_fail(c, RR_ERR_INVALID,
                         "%s: the node is reached twice (a node has one parent and appears in a scene once)",
                         where.c_str());
    c.visit[ni] = 1;
    gltf_mat4 local;
    rr_status s = gltf_local(c, n, where, &local);
    if (s != RR_OK)
        return s;
    gltf_mat4 w = gltf_mul(parent, local);
    if (n.mesh != -1) {
        if (n.mesh < 0 || static_cast<size_t>(n.mesh) >= c.g.meshes.size())
            return gltf_fail(c, RR_ERR_INVALID, "%s: mesh is %d: the file has %zu meshes", where.c_str(), n.mesh,
                             c.g.meshes.size());
        for (size_t pi = 0; pi < c.g.meshes[static_cast<size_t>(n.mesh)].primitives.size() && s == RR_OK; pi++)
            s = gltf_add_primitive(c, ni, static_cast<size_t>(n.mesh), pi, w);
    }
    if (s == RR_OK)
        s = gltf_add_light(c, ni, where, w);
    for (size_t k = 0; k < n.children.size() && s == RR_OK; k++) {
        int child = n.children[k];
        if (child < 0 || static_cast<size_t>(child) >= c.g.nodes.size())
            return gltf_fail(c, RR_ERR_INVALID, "%s: children[%zu] is %d: the file has %zu nodes", where.c_str(), k,
                             child, c.g.nodes.size());
        s = gltf_walk(c, static_cast<size_t>(child), w, depth + 1);
    }
    c.visit[ni] = 2;
    return s;
}

/* The default scene's roots, or every node that is nobody's child. */
rr_status gltf_roots(const gltf_ctx &c, std::vector<int> *roots, std::string *what)
{
    const tinygltf::Model &g = c.g;
    if (g.scenes.empty()) {
        std::vector<unsigned char> child(g.nodes.size(), 0);
        for (const tinygltf::Node &n : g.nodes)
            for (int k : n.children)
                if (k >= 0 && static_cast<size_t>(k) < g.nodes.size())
                    child[static_cast<size_t>(k)] = 1;
        for (size_t i = 0; i < g.nodes.size(); i++)
            if (!child[i])
                roots->push_back(static_cast<int>(i));
        *what = "root nodes";
        return RR_OK;
    }
    int scene = g.defaultScene == -1 ? 0 : g.defaultScene;
    if (scene < 0 || static_cast<size_t>(scene) >= g.scenes.size())
        return gltf_fail(c, RR_ERR_INVALID, "scene is %d: the file has %zu scenes", scene, g.scenes.size());
    *roots = g.scenes[static_cast<size_t>(scene)].nodes;
    *what = "scenes[" + std::to_string(scene) + "].nodes";
    return RR_OK;
}

rr_status gltf_load(gltf_ctx &c)
{
    rr_status s = gltf_check_extensions(c);
    if (s == RR_OK)
        s = gltf_add_materials(c);
    std::vector<int> roots;
    std::string what;
    if (s == RR_OK)
        s = gltf_roots(c, &roots, &what);
    if (s != RR_OK)
        return s;
    c.visit.assign(c.g.nodes.size(), 0);
    for (size_t k = 0; k < roots.size(); k++) {
        if (roots[k] < 0 || static_cast<size_t>(roots[k]) >= c.g.nodes.size())
            return gltf_fail(c, RR_ERR_INVALID, "%s[%zu] is %d: the file has %zu nodes", what.c_str(), k, roots[k],
                             c.g.nodes.size());
        if ((s = gltf_walk(c, static_cast<size_t>(roots[k]), gltf_identity(), 1)) != RR_OK)
            return s;
    }
    c.m->dropped_cameras = c.g.cameras.size();
    return RR_OK;
}

} // namespace

extern "C" rr_status imp__load_gltf(const char *path, int binary, imp_model *m, rr_error *err)
{
    try {
        tinygltf::Model g;
        rr_status s = gltf_read(path, binary, &g, err);
        if (s != RR_OK)
            return s;
        gltf_ctx c(path, g, m, err);
        return gltf_load(c);
    } catch (const std::bad_alloc &) {
        return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory", path);
    } catch (...) {
        return rr_error_set(err, RR_ERR_INTERNAL, "%s: internal error (unexpected C++ exception) in the glTF reader",
                            path);
    }
}
