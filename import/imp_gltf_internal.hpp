/* imp_gltf_internal.hpp - private to the glTF reader: what imp_gltf.cpp
 * (files, nodes, meshes, lights) and imp_gltf_material.cpp (materials) share. */
#ifndef IMP_GLTF_INTERNAL_HPP
#define IMP_GLTF_INTERNAL_HPP

#include <tiny_gltf.h>

#include <string>
#include <vector>

extern "C" {
#include "imp_internal.h"
}

namespace imp_gltf {

/* Decoded base-colour images, once each: mean colour or failure. */
enum gltf_img_state { GLTF_IMG_UNTRIED = 0, GLTF_IMG_OK, GLTF_IMG_BAD };

struct gltf_ctx {
    const char *path;
    const tinygltf::Model &g;
    imp_model *m;
    rr_error *err;
    long default_material = -1;           /* index once added */
    std::vector<unsigned char> visit;     /* per node: 0 new, 1 on the current path, 2 done */
    std::vector<unsigned char> img_state; /* gltf_img_state per image */
    std::vector<rr_rgb> img_mean;
    std::vector<double> pos, nrm; /* scratch, reused by every primitive */
    std::vector<uint32_t> idx, tris;

    gltf_ctx(const char *p, const tinygltf::Model &model, imp_model *out, rr_error *e)
        : path(p), g(model), m(out), err(e)
    {
    }
};

/* Fails with "PATH: message" (printf-style). */
rr_status gltf_fail(const gltf_ctx &c, rr_status code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* A string from the file, fit for a one-line message: at most max bytes. */
std::string gltf_clip(const std::string &s, size_t max);
/* "mesh 'Cube' (meshes[2])", or "meshes[2]" when it has no name. */
std::string gltf_label(const char *kind, const std::string &name, const char *array, size_t i);
/* v must be finite and in [lo, hi] (hi < 0: no upper bound). */
rr_status gltf_check_factor(const gltf_ctx &c, const std::string &where, const std::string &what, double v, double lo,
                            double hi);
/* v must have n values, each finite and in [0, hi]. */
rr_status gltf_check_array(const gltf_ctx &c, const std::string &where, const std::string &what,
                           const std::vector<double> &v, size_t n, double hi);

/* ---- materials (imp_gltf_material.cpp) ---- */

/* Every material of the file, in file order, into c.m. */
rr_status gltf_add_materials(gltf_ctx &c);
/* Index of the material for a primitive with material index mat (-1: none,
 * then a "default" material is added once). */
rr_status gltf_primitive_material(gltf_ctx &c, const std::string &where, int mat, uint32_t *out);

} // namespace imp_gltf

#endif
