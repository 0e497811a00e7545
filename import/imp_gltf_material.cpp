/* imp_gltf_material.cpp - glTF materials as radray materials, for the glTF
 * reader (imp_gltf.cpp; the mapping table is in notes/import.md): every
 * factor checked, base-colour textures reduced to their mean colour in linear
 * light (decoded once each with stb_image, a bad image dropped with a note),
 * metallic-roughness and the extensions mapped, and what was approximated
 * noted per material. */
#include <stb/stb_image.h>

#include <cmath>
#include <string>
#include <vector>

#include "imp_gltf_internal.hpp"

using namespace imp_gltf;

namespace {

/* KHR_materials_emissive_strength's factor (1 without the extension). */
rr_status gltf_emissive_strength(const gltf_ctx &c, const tinygltf::Material &mat, const std::string &where,
                                 double *out)
{
    *out = 1.0;
    auto it = mat.extensions.find("KHR_materials_emissive_strength");
    if (it == mat.extensions.end() || !it->second.IsObject() || !it->second.Has("emissiveStrength"))
        return RR_OK;
    const char *what = "extensions.KHR_materials_emissive_strength.emissiveStrength";
    const tinygltf::Value &v = it->second.Get("emissiveStrength");
    if (!v.IsNumber())
        return gltf_fail(c, RR_ERR_INVALID, "%s: %s is not a number", where.c_str(), what);
    *out = v.GetNumberAsDouble();
    return gltf_check_factor(c, where, what, *out, 0.0, -1.0);
}

rr_status gltf_check_material(const gltf_ctx &c, const tinygltf::Material &mat, const std::string &where)
{
    const tinygltf::PbrMetallicRoughness &pbr = mat.pbrMetallicRoughness;
    /* tinygltf 2.7.0 silently keeps [1, 1, 1, 1] for a baseColorFactor of the
     * wrong length; its legacy parameter map has what the file says */
    auto legacy = mat.values.find("baseColorFactor");
    bool bad_length = legacy != mat.values.end() && legacy->second.number_array.size() != 4;
    const std::vector<double> &base = bad_length ? legacy->second.number_array : pbr.baseColorFactor;
    rr_status s = gltf_check_array(c, where, "pbrMetallicRoughness.baseColorFactor", base, 4, 1.0);
    if (s == RR_OK)
        s = gltf_check_factor(c, where, "pbrMetallicRoughness.metallicFactor", pbr.metallicFactor, 0.0, 1.0);
    if (s == RR_OK)
        s = gltf_check_factor(c, where, "pbrMetallicRoughness.roughnessFactor", pbr.roughnessFactor, 0.0, 1.0);
    if (s == RR_OK)
        s = gltf_check_array(c, where, "emissiveFactor", mat.emissiveFactor, 3, -1.0);
    return s;
}

/* Mean linear colour of a decoded image; false when its layout is not what
 * LoadImageData promises (8 or 16 bits, 1..4 channels, w x h pixels). */
bool gltf_image_mean(const tinygltf::Image &img, rr_rgb *mean)
{
    if (img.width < 1 || img.height < 1 || img.component < 1 || img.component > 4 || (img.bits != 8 && img.bits != 16))
        return false;
    size_t n = static_cast<size_t>(img.width) * static_cast<size_t>(img.height) * static_cast<size_t>(img.component);
    if (img.image.size() != n * static_cast<size_t>(img.bits / 8))
        return false;
    size_t npx = static_cast<size_t>(img.width) * static_cast<size_t>(img.height);
    if (img.bits == 8) {
        *mean = imp__srgb_mean(img.image.data(), npx, img.component);
        return true;
    }
    std::vector<unsigned char> high(n); /* 16 bits: the high byte of each */
    for (size_t i = 0; i < n; i++) {
        uint16_t v;
        memcpy(&v, &img.image[2 * i], sizeof v);
        high[i] = static_cast<unsigned char>(v >> 8);
    }
    *mean = imp__srgb_mean(high.data(), npx, img.component);
    return true;
}

/* Mean of the base-colour texture tex; *ok = false when it has no image that
 * decodes (the texture is then dropped). */
rr_status gltf_texture_mean(gltf_ctx &c, const std::string &where, int tex, rr_rgb *mean, bool *ok)
{
    *ok = false;
    if (tex < 0 || static_cast<size_t>(tex) >= c.g.textures.size())
        return gltf_fail(c, RR_ERR_INVALID,
                         "%s: pbrMetallicRoughness.baseColorTexture.index is %d: the file has %zu textures",
                         where.c_str(), tex, c.g.textures.size());
    int src = c.g.textures[static_cast<size_t>(tex)].source;
    if (src < 0)
        return RR_OK; /* no core image (e.g. only an extension's source) */
    if (static_cast<size_t>(src) >= c.g.images.size())
        return gltf_fail(c, RR_ERR_INVALID, "%s: textures[%d].source is %d: the file has %zu images", where.c_str(),
                         tex, src, c.g.images.size());
    size_t i = static_cast<size_t>(src);
    if (c.img_state[i] == GLTF_IMG_UNTRIED) {
        const std::vector<unsigned char> &bytes = c.g.images[i].image;
        tinygltf::Image dec;
        std::string terr, twarn;
        int w = 0, h = 0, ch = 0; /* the size first: a small file can hold a huge image */
        bool fits = !bytes.empty() && bytes.size() <= INT32_MAX &&
                    stbi_info_from_memory(bytes.data(), static_cast<int>(bytes.size()), &w, &h, &ch) && w > 0 &&
                    h > 0 && static_cast<size_t>(w) * static_cast<size_t>(h) <= IMP_TEXTURE_MAX_PIXELS;
        bool decoded = fits &&
                       tinygltf::LoadImageData(&dec, src, &terr, &twarn, 0, 0, bytes.data(),
                                               static_cast<int>(bytes.size()), nullptr);
        c.img_state[i] = decoded && gltf_image_mean(dec, &c.img_mean[i]) ? GLTF_IMG_OK : GLTF_IMG_BAD;
    }
    *ok = c.img_state[i] == GLTF_IMG_OK;
    if (*ok)
        *mean = c.img_mean[i];
    return RR_OK;
}

bool gltf_has_ext(const tinygltf::ExtensionMap &ext, const char *name) { return ext.find(name) != ext.end(); }

/* Notes for what the mapping cannot keep: other textures, transparency. */
unsigned gltf_material_notes(const tinygltf::Material &mat)
{
    unsigned notes = 0;
    if (mat.normalTexture.index >= 0 || mat.occlusionTexture.index >= 0 || mat.emissiveTexture.index >= 0 ||
        mat.pbrMetallicRoughness.metallicRoughnessTexture.index >= 0)
        notes |= IMP_NOTE_TEXTURE_DROP;
    if (mat.alphaMode == "BLEND" || mat.alphaMode == "MASK" ||
        gltf_has_ext(mat.extensions, "KHR_materials_transmission") ||
        gltf_has_ext(mat.extensions, "KHR_materials_volume"))
        notes |= IMP_NOTE_TRANSPARENT;
    return notes;
}

rr_status gltf_map_material(gltf_ctx &c, size_t i, imp_material *dst)
{
    const tinygltf::Material &mat = c.g.materials[i];
    const tinygltf::PbrMetallicRoughness &pbr = mat.pbrMetallicRoughness;
    std::string where = gltf_label("material", mat.name, "materials", i);
    double strength = 1.0;
    rr_status s = gltf_check_material(c, mat, where);
    if (s == RR_OK)
        s = gltf_emissive_strength(c, mat, where, &strength);
    if (s != RR_OK)
        return s;
    imp__name(dst->name, mat.name.c_str(), "material", i);
    dst->notes = gltf_material_notes(mat);
    rr_rgb base = rr_rgb_make(pbr.baseColorFactor[0], pbr.baseColorFactor[1], pbr.baseColorFactor[2]);
    if (pbr.baseColorTexture.index >= 0) {
        rr_rgb mean;
        bool ok;
        if ((s = gltf_texture_mean(c, where, pbr.baseColorTexture.index, &mean, &ok)) != RR_OK)
            return s;
        base = ok ? rr_rgb_mul(base, mean) : base;
        dst->notes |= ok ? IMP_NOTE_TEXTURE_AVG : IMP_NOTE_TEXTURE_DROP;
    }
    dst->emission =
        rr_rgb_scale(rr_rgb_make(mat.emissiveFactor[0], mat.emissiveFactor[1], mat.emissiveFactor[2]), strength);
    if (gltf_has_ext(mat.extensions, "KHR_materials_unlit")) {
        dst->diffuse = base;
        dst->notes |= IMP_NOTE_UNLIT;
    } else if (pbr.metallicFactor >= 0.99 && pbr.roughnessFactor <= 0.1) {
        dst->mirror = base; /* a polished metal */
    } else {
        dst->diffuse = base;
        dst->k = 1.0;
        if (pbr.metallicFactor > 0.01 || pbr.roughnessFactor < 0.5)
            dst->notes |= IMP_NOTE_ROUGH;
    }
    return RR_OK;
}

} // namespace

namespace imp_gltf {

rr_status gltf_add_materials(gltf_ctx &c)
{
    c.img_state.assign(c.g.images.size(), GLTF_IMG_UNTRIED);
    c.img_mean.assign(c.g.images.size(), rr_rgb_make(0, 0, 0));
    for (size_t i = 0; i < c.g.materials.size(); i++) {
        imp_material *dst = imp__add_material(c.m);
        if (!dst)
            return gltf_fail(c, RR_ERR_NOMEM, "out of memory for materials[%zu]", i);
        rr_status s = gltf_map_material(c, i, dst);
        if (s != RR_OK)
            return s;
    }
    return RR_OK;
}

/* Index of the material for a primitive with material index mat (-1: none). */
rr_status gltf_primitive_material(gltf_ctx &c, const std::string &where, int mat, uint32_t *out)
{
    if (mat >= 0 && static_cast<size_t>(mat) < c.g.materials.size()) {
        *out = static_cast<uint32_t>(mat);
        return RR_OK;
    }
    if (mat != -1)
        return gltf_fail(c, RR_ERR_INVALID, "%s: material is %d: the file has %zu materials", where.c_str(), mat,
                         c.g.materials.size());
    if (c.default_material < 0) {
        imp_material *dst = imp__add_material(c.m);
        if (!dst)
            return gltf_fail(c, RR_ERR_NOMEM, "out of memory for the default material");
        imp__name(dst->name, "default", "material", c.m->nmaterials - 1);
        dst->diffuse = rr_rgb_make(0.5, 0.5, 0.5);
        dst->notes = IMP_NOTE_DEFAULT;
        c.default_material = static_cast<long>(c.m->nmaterials - 1);
    }
    *out = static_cast<uint32_t>(c.default_material);
    return RR_OK;
}

} // namespace imp_gltf
