/* img_exr.c - OpenEXR files through the OpenEXR 3 C core API (openexr.h).
 *
 * Writing: one scanline part, channels R, G, B plus "<layer>.R/.G/.B" per
 * extra layer, all FLOAT or all HALF, ZIP compressed. The file is written to a
 * temporary next to the destination and renamed into place only once
 * exr_finish has written the chunk offset table and the data is on disk.
 *
 * Reading: the first part of a scanline or tiled (level 0) file, any
 * compression, half/float/uint channels, converted to float by the library's
 * decode pipeline straight into the rr_image buffer.
 *
 * Core API facts this file relies on (checked against 3.1.5):
 *  - the channel list is kept sorted by name (exr_add_channel inserts in
 *    order), and the encode/decode pipelines expose channels in that list
 *    order, which is also their order inside every chunk. So pipeline
 *    channels are matched to our buffers by name, never by position.
 *  - the library converts between the user type and the file type in both
 *    pipelines (FLOAT user data -> HALF file channel uses round-to-nearest-even),
 *    so no hand-written half conversion is needed.
 *  - errors arrive through the context's error handler; by default it prints
 *    to stderr. We install our own, which keeps the first message so that it
 *    can become part of the rr_error (library code must not print).
 */
#include "img.h"

#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <openexr.h>

/* Longest layer name: img_exr_layers hands names back in char[64]. */
#define IMG_LAYER_NAME_MAX 63
/* Channel names: a layer name plus ".R". */
#define IMG_CHAN_NAME_MAX (IMG_LAYER_NAME_MAX + 3)
/* Without the "long names" file flag, names are limited to 31 bytes. */
#define IMG_EXR_SHORT_NAME_MAX 31

/* First error message the library reported for one context. */
typedef struct img_exr_log {
    char msg[512];
} img_exr_log;

static void img_exr_on_error(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    void *ud = NULL;
    (void)code;
    if (!ctxt || exr_get_user_data(ctxt, &ud) != EXR_ERR_SUCCESS || !ud)
        return;
    img_exr_log *log = ud;
    /* The first message names the root cause; later ones are consequences. */
    if (log->msg[0] == '\0')
        snprintf(log->msg, sizeof log->msg, "%s", msg ? msg : "");
}

static exr_context_initializer_t img_exr_init(img_exr_log *log)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    log->msg[0] = '\0';
    init.error_handler_fn = img_exr_on_error;
    init.user_data = log;
    return init;
}

static const char *img_exr_reason(const img_exr_log *log, exr_result_t rv)
{
    return log->msg[0] ? log->msg : exr_get_default_error_message(rv);
}

/* ------------------------------------------------------------------ writing */

/* One file channel and where its values live in the caller's images. */
typedef struct img_exr_src {
    char name[IMG_CHAN_NAME_MAX + 1];
    const rr_image *img;
    int comp; /* 0, 1, 2 = R, G, B */
} img_exr_src;

static int img_layer_name_ok(const char *name)
{
    size_t n = strlen(name);
    if (n == 0 || n > IMG_LAYER_NAME_MAX)
        return 0;
    for (size_t i = 0; i < n; i++) {
        char c = name[i];
        int ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                 c == '-';
        if (!ok)
            return 0;
    }
    return 1;
}

/* Everything that can be checked before a temporary file exists. */
static rr_status img_exr_check_args(const char *path, const rr_image *rgb, const img_layer *layers, int nlayers,
                                    img_pixel_type type, rr_error *err)
{
    if (!rgb || !rgb->px || rgb->width <= 0 || rgb->height <= 0)
        return rr_error_set(err, RR_ERR_INVALID, "%s: cannot write EXR: the image is empty", path);
    /* The pipelines take the line stride (12 bytes a pixel) as int32_t. */
    if (rgb->width > INT32_MAX / (int)(3 * sizeof(float)))
        return rr_error_set(err, RR_ERR_LIMIT, "%s: cannot write EXR: %d pixels is too wide", path, rgb->width);
    if (type != IMG_FLOAT && type != IMG_HALF)
        return rr_error_set(err, RR_ERR_INVALID, "%s: cannot write EXR: unknown pixel type %d", path, (int)type);
    if (nlayers < 0 || (nlayers > 0 && !layers))
        return rr_error_set(err, RR_ERR_INVALID, "%s: cannot write EXR: invalid layer list", path);
    /* 3 channels per layer must fit the pipeline's int16_t channel count. */
    if (nlayers > 10000)
        return rr_error_set(err, RR_ERR_LIMIT, "%s: cannot write EXR: too many layers (%d)", path, nlayers);
    for (int i = 0; i < nlayers; i++) {
        const img_layer *l = &layers[i];
        if (!l->name || !img_layer_name_ok(l->name))
            return rr_error_set(err, RR_ERR_INVALID,
                                "%s: cannot write EXR: layer %d: name '%s' must be 1 to %d letters, digits, '_' or '-'",
                                path, i, l->name ? l->name : "(null)", IMG_LAYER_NAME_MAX);
        if (!l->image || !l->image->px || l->image->width != rgb->width || l->image->height != rgb->height)
            return rr_error_set(err, RR_ERR_INVALID,
                                "%s: cannot write EXR: layer '%s' is not a %d x %d image like the main image", path,
                                l->name, rgb->width, rgb->height);
        for (int j = 0; j < i; j++)
            if (strcmp(layers[j].name, l->name) == 0)
                return rr_error_set(err, RR_ERR_INVALID, "%s: cannot write EXR: layer '%s' given twice", path,
                                    l->name);
    }
    return RR_OK;
}

static const img_exr_src *img_exr_find_src(const img_exr_src *srcs, int n, const char *name)
{
    for (int i = 0; i < n; i++)
        if (strcmp(srcs[i].name, name) == 0)
            return &srcs[i];
    return NULL;
}

/* Defines the part (header attributes and channels) of a fresh write context. */
static exr_result_t img_exr_define(exr_context_t ctx, const rr_image *rgb, const img_exr_src *srcs, int nsrcs,
                                   exr_pixel_type_t ptype, const img_attr *attrs, int nattrs)
{
    int part = 0;
    exr_result_t rv = exr_add_part(ctx, NULL, EXR_STORAGE_SCANLINE, &part);
    if (rv != EXR_ERR_SUCCESS)
        return rv;

    /* The whole picture is stored: data window = display window, origin at
     * (0, 0); square pixels; the default screen window (center 0, width 1). */
    exr_attr_box2i_t win;
    win.min.x = 0;
    win.min.y = 0;
    win.max.x = rgb->width - 1;
    win.max.y = rgb->height - 1;
    exr_attr_v2f_t center;
    center.x = 0.0f;
    center.y = 0.0f;
    /* ZIP rather than ZIPS or NONE: lossless like both, and deflating 16
     * scanlines at once compresses renders clearly better than ZIPS (one line
     * per chunk); it is also what renderers (Blender, Arnold) write by
     * default, so every reader handles it. */
    rv = exr_initialize_required_attr(ctx, part, &win, &win, 1.0f, &center, 1.0f, EXR_LINEORDER_INCREASING_Y,
                                      EXR_COMPRESSION_ZIP);
    if (rv != EXR_ERR_SUCCESS)
        return rv;

    /* Long layer names need the "long names" flag (readers since OpenEXR
     * 1.7); set it only when needed so ordinary files stay maximally portable. */
    for (int i = 0; i < nsrcs; i++) {
        if (strlen(srcs[i].name) > IMG_EXR_SHORT_NAME_MAX) {
            rv = exr_set_longname_support(ctx, 1);
            if (rv != EXR_ERR_SUCCESS)
                return rv;
            break;
        }
    }
    for (int i = 0; i < nattrs; i++) {
        rv = exr_attr_set_string(ctx, part, attrs[i].name, attrs[i].value);
        if (rv != EXR_ERR_SUCCESS)
            return rv;
    }
    for (int i = 0; i < nsrcs; i++) {
        /* Colour values: perceptually logarithmic, as the library docs say for R, G, B. */
        rv = exr_add_channel(ctx, part, srcs[i].name, ptype, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
        if (rv != EXR_ERR_SUCCESS)
            return rv;
    }
    return exr_write_header(ctx);
}

/* Encodes and writes every chunk, top to bottom. */
static exr_result_t img_exr_write_chunks(exr_context_t ctx, const rr_image *rgb, const img_exr_src *srcs, int nsrcs)
{
    const int part = 0;
    int32_t lines = 0;
    exr_result_t rv = exr_get_scanlines_per_chunk(ctx, part, &lines);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    if (lines <= 0)
        return EXR_ERR_INVALID_ARGUMENT;

    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int have_pipe = 0;
    const size_t pixel_bytes = 3 * sizeof(float);
    for (int y = 0; y < rgb->height && rv == EXR_ERR_SUCCESS; y += lines) {
        exr_chunk_info_t ci;
        rv = exr_write_scanline_chunk_info(ctx, part, y, &ci);
        if (rv != EXR_ERR_SUCCESS)
            break;
        /* The pipeline is built once and updated per chunk so its buffers are reused. */
        rv = have_pipe ? exr_encoding_update(ctx, part, &ci, &enc) : exr_encoding_initialize(ctx, part, &ci, &enc);
        if (rv != EXR_ERR_SUCCESS)
            break;
        have_pipe = 1;
        for (int c = 0; c < enc.channel_count; c++) {
            exr_coding_channel_info_t *ch = &enc.channels[c];
            const img_exr_src *s = img_exr_find_src(srcs, nsrcs, ch->channel_name);
            if (!s) {
                rv = EXR_ERR_INVALID_ARGUMENT;
                break;
            }
            /* Interleaved RGB floats: the next pixel is 3 floats on, the
             * next line a full row on. ci.start_y is the absolute y (the
             * data window starts at 0). */
            ch->encode_from_ptr = (const uint8_t *)(rr_image_at(s->img, 0, ci.start_y) + s->comp);
            ch->user_pixel_stride = (int32_t)pixel_bytes;
            ch->user_line_stride = (int32_t)(pixel_bytes * (size_t)rgb->width);
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)sizeof(float);
        }
        if (rv != EXR_ERR_SUCCESS)
            break;
        /* Routines are chosen once the channel layout is known (first chunk). */
        if (y == 0)
            rv = exr_encoding_choose_default_routines(ctx, part, &enc);
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_encoding_run(ctx, part, &enc);
    }
    if (have_pipe)
        exr_encoding_destroy(ctx, &enc);
    return rv;
}

/* exr_finish closes the file but does not sync it; a rename is only safe
 * after the data is on disk (the same guarantee rr_atomic_commit gives). */
static int img_exr_sync(const char *tmp)
{
    int fd = open(tmp, O_RDONLY);
    if (fd < 0)
        return -1;
    int bad = fsync(fd) != 0 && errno != EINVAL;
    int e = errno;
    close(fd);
    errno = e;
    return bad ? -1 : 0;
}

rr_status img_write_exr(const char *path, const rr_image *rgb, const img_layer *layers, int nlayers,
                        img_pixel_type type, rr_error *err)
{
    return img_write_exr_attrs(path, rgb, layers, nlayers, type, NULL, 0, err);
}

rr_status img_write_exr_attrs(const char *path, const rr_image *rgb, const img_layer *layers, int nlayers,
                              img_pixel_type type, const img_attr *attrs, int nattrs, rr_error *err)
{
    for (int i = 0; i < nattrs; i++)
        if (!attrs[i].name || !attrs[i].name[0] || !attrs[i].value || strlen(attrs[i].name) > 255 ||
            strlen(attrs[i].value) > 65535)
            return rr_error_set(err, RR_ERR_INVALID, "%s: EXR attribute %d needs a name (at most 255 bytes) and a "
                                "value (at most 65535)", path, i);
    rr_status st = img_exr_check_args(path, rgb, layers, nlayers, type, err);
    if (st != RR_OK)
        return st;

    int nsrcs = 3 * (1 + nlayers);
    img_exr_src *srcs = calloc((size_t)nsrcs, sizeof *srcs);
    if (!srcs)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory writing EXR", path);
    static const char comp_names[3] = {'R', 'G', 'B'};
    for (int l = 0; l <= nlayers; l++) {
        for (int c = 0; c < 3; c++) {
            img_exr_src *s = &srcs[3 * l + c];
            if (l == 0) {
                snprintf(s->name, sizeof s->name, "%c", comp_names[c]);
                s->img = rgb;
            } else {
                snprintf(s->name, sizeof s->name, "%s.%c", layers[l - 1].name, comp_names[c]);
                s->img = layers[l - 1].image;
            }
            s->comp = c;
        }
    }

    char tmp[4096];
    st = rr_file_tmpname(path, tmp, sizeof tmp, err);
    if (st != RR_OK) {
        free(srcs);
        return st;
    }

    img_exr_log log;
    exr_context_initializer_t init = img_exr_init(&log);
    exr_context_t ctx = NULL;
    /* WRITE_FILE_DIRECTLY: tmp is already our private temporary; the library's
     * own temp-file mode would add a second, uncontrolled name in the folder. */
    exr_result_t rv = exr_start_write(&ctx, tmp, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS)
        rv = img_exr_define(ctx, rgb, srcs, nsrcs, type == IMG_HALF ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT, attrs,
                            nattrs);
    if (rv == EXR_ERR_SUCCESS)
        rv = img_exr_write_chunks(ctx, rgb, srcs, nsrcs);
    /* exr_finish writes the chunk offset table, so its result counts too;
     * it must run even after a failure to free the context. */
    if (ctx) {
        exr_result_t frv = exr_finish(&ctx);
        if (rv == EXR_ERR_SUCCESS)
            rv = frv;
    }
    free(srcs);
    if (rv != EXR_ERR_SUCCESS) {
        remove(tmp);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot write EXR: %s", path, img_exr_reason(&log, rv));
    }
    if (img_exr_sync(tmp) != 0) {
        int e = errno;
        remove(tmp);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot write EXR: %s", path, strerror(e));
    }
    return rr_file_replace(tmp, path, err);
}

/* ------------------------------------------------------------------ reading */

/* Maps a core result to our codes: unreadable -> IO, valid but unsupported
 * (e.g. DWAA, which the 3.1 core cannot decode) -> INVALID, malformed -> PARSE. */
static rr_status img_exr_status(exr_result_t rv)
{
    switch (rv) {
    case EXR_ERR_OUT_OF_MEMORY:
        return RR_ERR_NOMEM;
    case EXR_ERR_FEATURE_NOT_IMPLEMENTED:
        return RR_ERR_INVALID;
    case EXR_ERR_FILE_ACCESS:
    case EXR_ERR_READ_IO:
        return RR_ERR_IO;
    default:
        return RR_ERR_PARSE;
    }
}

static rr_status img_exr_open(const char *path, exr_context_t *ctx, img_exr_log *log, rr_error *err)
{
    exr_context_initializer_t init = img_exr_init(log);
    *ctx = NULL;
    exr_result_t rv = exr_start_read(ctx, path, &init);
    if (rv != EXR_ERR_SUCCESS) {
        if (*ctx)
            exr_finish(ctx);
        return rr_error_set(err, img_exr_status(rv), "%s: cannot read EXR: %s", path, img_exr_reason(log, rv));
    }
    int parts = 0;
    rv = exr_get_count(*ctx, &parts);
    if (rv != EXR_ERR_SUCCESS || parts < 1) {
        exr_finish(ctx);
        return rr_error_set(err, RR_ERR_PARSE, "%s: cannot read EXR: the file has no image part", path);
    }
    return RR_OK;
}

/* Length of the layer prefix of a channel name (text before the last '.'),
 * or 0 when the channel belongs to no layer. */
static size_t img_exr_prefix_len(const char *name)
{
    const char *dot = strrchr(name, '.');
    return dot ? (size_t)(dot - name) : 0;
}

/* Collects the unique layer prefixes of part 0 in channel-list (alphabetical)
 * order. Names too long for char[64] are skipped since they cannot be
 * returned whole. Returns the number found (which may exceed max; only max
 * are stored). */
static int img_exr_collect_layers(const exr_attr_chlist_t *ch, char names[][64], int max)
{
    int found = 0;
    for (int i = 0; i < ch->num_channels; i++) {
        const char *name = ch->entries[i].name.str;
        size_t n = img_exr_prefix_len(name);
        if (n == 0 || n > IMG_LAYER_NAME_MAX)
            continue;
        /* Channels of one layer are not always adjacent in the sorted list
         * ("a.C.R" sorts between "a.B" and "a.G"), so look at every earlier one. */
        int dup = 0;
        for (int j = 0; j < i && !dup; j++) {
            const char *other = ch->entries[j].name.str;
            dup = img_exr_prefix_len(other) == n && memcmp(other, name, n) == 0;
        }
        if (dup)
            continue;
        if (found < max) {
            memcpy(names[found], name, n);
            names[found][n] = '\0';
        }
        found++;
    }
    return found;
}

rr_status img_exr_layers(const char *path, char names[][64], int max, int *count, rr_error *err)
{
    *count = 0;
    exr_context_t ctx;
    img_exr_log log;
    rr_status st = img_exr_open(path, &ctx, &log, err);
    if (st != RR_OK)
        return st;
    const exr_attr_chlist_t *ch = NULL;
    exr_result_t rv = exr_get_channels(ctx, 0, &ch);
    if (rv != EXR_ERR_SUCCESS || !ch) {
        st = rr_error_set(err, RR_ERR_PARSE, "%s: cannot read EXR: %s", path, img_exr_reason(&log, rv));
    } else {
        int found = img_exr_collect_layers(ch, names, max > 0 ? max : 0);
        *count = found < max ? found : (max > 0 ? max : 0);
    }
    exr_finish(&ctx);
    return st;
}

rr_status img_read_exr_attr(const char *path, const char *name, char *buf, size_t n, rr_error *err)
{
    exr_context_t ctx;
    img_exr_log log;
    rr_status st = img_exr_open(path, &ctx, &log, err);
    if (st != RR_OK)
        return st;
    int32_t len = 0;
    const char *v = NULL;
    exr_result_t rv = exr_attr_get_string(ctx, 0, name, &len, &v);
    if (rv != EXR_ERR_SUCCESS || !v)
        st = rr_error_set(err, RR_ERR_INVALID, "%s: no string attribute '%s'", path, name);
    else if (n > 0)
        snprintf(buf, n, "%.*s", (int)len, v);
    exr_finish(&ctx);
    return st;
}

/* "the file's layers are: a, b" or "the file has no extra layers" for errors. */
static void img_exr_describe_layers(const exr_attr_chlist_t *ch, char *out, size_t out_size)
{
    char names[16][64];
    int found = img_exr_collect_layers(ch, names, 16);
    if (found == 0) {
        snprintf(out, out_size, "the file has no extra layers");
        return;
    }
    size_t n = (size_t)snprintf(out, out_size, "the file's layers are:");
    for (int i = 0; i < found && i < 16 && n < out_size; i++)
        n += (size_t)snprintf(out + n, out_size - n, "%s %s", i ? "," : "", names[i]);
    if (found > 16 && n < out_size)
        snprintf(out + n, out_size - n, " and %d more", found - 16);
}

/* Fills idx[0..2] with the channel-list positions of <prefix>R, G, B. */
static int img_exr_find_rgb(const exr_attr_chlist_t *ch, const char *layer, int idx[3])
{
    static const char comp_names[3] = {'R', 'G', 'B'};
    for (int c = 0; c < 3; c++) {
        char want[IMG_CHAN_NAME_MAX + 2];
        if (layer && layer[0])
            snprintf(want, sizeof want, "%s.%c", layer, comp_names[c]);
        else
            snprintf(want, sizeof want, "%c", comp_names[c]);
        idx[c] = -1;
        for (int i = 0; i < ch->num_channels; i++)
            if (strcmp(ch->entries[i].name.str, want) == 0)
                idx[c] = i;
        if (idx[c] < 0)
            return 0;
    }
    return 1;
}

/* Decodes one chunk into out. The chunk's pixel rectangle starts at
 * (ci->start_x, ci->start_y) in file coordinates; (ox, oy) is the data
 * window origin, which is row 0 / column 0 of out. */
static exr_result_t img_exr_decode_chunk(exr_context_t ctx, const exr_chunk_info_t *ci, exr_decode_pipeline_t *dec,
                                         int *have_pipe, const int idx[3], int ox, int oy, rr_image *out)
{
    exr_result_t rv = *have_pipe ? exr_decoding_update(ctx, 0, ci, dec) : exr_decoding_initialize(ctx, 0, ci, dec);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    int first = !*have_pipe;
    *have_pipe = 1;
    if (ci->start_x < ox || ci->start_y < oy || ci->start_x - ox + ci->width > out->width ||
        ci->start_y - oy + ci->height > out->height)
        return EXR_ERR_CORRUPT_CHUNK;
    const size_t pixel_bytes = 3 * sizeof(float);
    /* The pipeline's channels are the whole channel list in list order, so
     * position i here is entry i of exr_get_channels. Channels we do not
     * want get a NULL pointer, which the unpacker skips. */
    for (int c = 0; c < dec->channel_count; c++) {
        exr_coding_channel_info_t *ch = &dec->channels[c];
        ch->decode_to_ptr = NULL;
        for (int k = 0; k < 3; k++) {
            if (idx[k] != c)
                continue;
            ch->decode_to_ptr = (uint8_t *)(rr_image_at(out, ci->start_x - ox, ci->start_y - oy) + k);
            ch->user_pixel_stride = (int32_t)pixel_bytes;
            ch->user_line_stride = (int32_t)(pixel_bytes * (size_t)out->width);
            /* Ask for float whatever the file stores: halves are converted. */
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)sizeof(float);
        }
    }
    if (first) {
        rv = exr_decoding_choose_default_routines(ctx, 0, dec);
        if (rv != EXR_ERR_SUCCESS)
            return rv;
    }
    return exr_decoding_run(ctx, 0, dec);
}

/* Decodes every chunk of part 0 (scanlines, or the tiles of level 0). */
static exr_result_t img_exr_decode_all(exr_context_t ctx, exr_storage_t storage, const exr_attr_box2i_t *dw,
                                       const int idx[3], rr_image *out)
{
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int have_pipe = 0;
    exr_result_t rv = EXR_ERR_SUCCESS;
    exr_chunk_info_t ci;
    if (storage == EXR_STORAGE_SCANLINE) {
        int32_t lines = 0;
        rv = exr_get_scanlines_per_chunk(ctx, 0, &lines);
        if (rv == EXR_ERR_SUCCESS && lines <= 0)
            rv = EXR_ERR_INVALID_ATTR;
        for (int64_t y = dw->min.y; rv == EXR_ERR_SUCCESS && y <= dw->max.y; y += lines) {
            rv = exr_read_scanline_chunk_info(ctx, 0, (int)y, &ci);
            if (rv == EXR_ERR_SUCCESS)
                rv = img_exr_decode_chunk(ctx, &ci, &dec, &have_pipe, idx, dw->min.x, dw->min.y, out);
        }
    } else {
        /* Level (0, 0) is the full-resolution image for one-level, mipmap
         * and ripmap files alike. */
        int32_t tw = 0, th = 0;
        rv = exr_get_tile_sizes(ctx, 0, 0, 0, &tw, &th);
        if (rv == EXR_ERR_SUCCESS && (tw <= 0 || th <= 0))
            rv = EXR_ERR_INVALID_ATTR;
        int ntx = rv == EXR_ERR_SUCCESS ? (int)(((int64_t)out->width + tw - 1) / tw) : 0;
        int nty = rv == EXR_ERR_SUCCESS ? (int)(((int64_t)out->height + th - 1) / th) : 0;
        for (int ty = 0; rv == EXR_ERR_SUCCESS && ty < nty; ty++) {
            for (int tx = 0; rv == EXR_ERR_SUCCESS && tx < ntx; tx++) {
                rv = exr_read_tile_chunk_info(ctx, 0, tx, ty, 0, 0, &ci);
                /* A tile chunk's start_x/start_y are tile indices, not pixels. */
                if (rv == EXR_ERR_SUCCESS) {
                    ci.start_x = dw->min.x + tx * tw;
                    ci.start_y = dw->min.y + ty * th;
                    rv = img_exr_decode_chunk(ctx, &ci, &dec, &have_pipe, idx, dw->min.x, dw->min.y, out);
                }
            }
        }
    }
    if (have_pipe)
        exr_decoding_destroy(ctx, &dec);
    return rv;
}

rr_status img_read_exr(const char *path, const char *layer, rr_image *out, rr_error *err)
{
    exr_context_t ctx;
    img_exr_log log;
    rr_status st = img_exr_open(path, &ctx, &log, err);
    if (st != RR_OK)
        return st;

    exr_storage_t storage = EXR_STORAGE_LAST_TYPE;
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *ch = NULL;
    exr_result_t rv = exr_get_storage(ctx, 0, &storage);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_data_window(ctx, 0, &dw);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_channels(ctx, 0, &ch);
    if (rv != EXR_ERR_SUCCESS || !ch) {
        st = rr_error_set(err, RR_ERR_PARSE, "%s: cannot read EXR: %s", path, img_exr_reason(&log, rv));
        goto done;
    }
    if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED) {
        st = rr_error_set(err, RR_ERR_INVALID, "%s: cannot read EXR: deep images are not supported", path);
        goto done;
    }

    int idx[3];
    if (!img_exr_find_rgb(ch, layer, idx)) {
        char avail[1024];
        img_exr_describe_layers(ch, avail, sizeof avail);
        if (layer && layer[0])
            st = rr_error_set(err, RR_ERR_INVALID, "%s: no layer '%s' (channels %s.R, %s.G, %s.B); %s", path,
                              layer, layer, layer, layer, avail);
        else
            st = rr_error_set(err, RR_ERR_INVALID, "%s: no R, G, B channels; %s", path, avail);
        goto done;
    }
    for (int k = 0; k < 3; k++) {
        const exr_attr_chlist_entry_t *e = &ch->entries[idx[k]];
        if (e->x_sampling != 1 || e->y_sampling != 1) {
            st = rr_error_set(err, RR_ERR_INVALID, "%s: cannot read EXR: channel %s is subsampled", path,
                              e->name.str);
            goto done;
        }
    }

    int64_t w = (int64_t)dw.max.x - dw.min.x + 1, h = (int64_t)dw.max.y - dw.min.y + 1;
    if (w <= 0 || h <= 0 || w > INT32_MAX || h > INT32_MAX) {
        st = rr_error_set(err, RR_ERR_PARSE, "%s: cannot read EXR: invalid data window", path);
        goto done;
    }
    /* The pipelines take the line stride (12 bytes a pixel) as int32_t. */
    if (w > INT32_MAX / (int64_t)(3 * sizeof(float))) {
        st = rr_error_set(err, RR_ERR_LIMIT, "%s: cannot read EXR: %lld pixels is too wide", path, (long long)w);
        goto done;
    }
    rr_image img = {0};
    st = rr_image_init(&img, (int)w, (int)h, err);
    if (st != RR_OK) {
        rr_error_prefix(err, "%s", path);
        goto done;
    }
    rv = img_exr_decode_all(ctx, storage, &dw, idx, &img);
    if (rv != EXR_ERR_SUCCESS) {
        rr_image_free(&img);
        st = rr_error_set(err, img_exr_status(rv), "%s: cannot read EXR pixels: %s", path, img_exr_reason(&log, rv));
        goto done;
    }
    *out = img;
    st = RR_OK;
done:
    exr_finish(&ctx);
    return st;
}
