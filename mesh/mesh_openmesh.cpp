/* mesh_openmesh.cpp - mesh_load: the only C++ in radray, a shim over OpenMesh's
 * readers (see mesh.h for the contract, mesh_internal.h for the hand-over).
 *
 * How a file is read:
 *  1. The file is read into memory once (core's rr_file_read_all): OpenMesh
 *     then parses these same bytes from a memory stream, so what was checked
 *     is what gets read.
 *  2. A strict pre-check per format (mesh__check, in C: mesh_formats.c and
 *     mesh_ply.c) validates every count, index and coordinate, because
 *     OpenMesh 9.0's readers misread or loop on bad input; OpenMesh only ever
 *     sees input it handles correctly.
 *  3. OpenMesh reads into a PolyMesh through mesh__recorder, an ImporterT that
 *     also records each polygon exactly as the reader passed it. That matters
 *     because ImporterT on its own drops faces with a repeated vertex and, for
 *     a face that would make the halfedge structure non-manifold (a third face
 *     on an edge, or a face reversing a neighbour's orientation), adds it on
 *     fresh copies of its vertices: the recorded polygons keep the file's own
 *     indexing, so mesh_analyze sees the real topology and degenerate faces
 *     are kept, as mesh.h promises.
 *  4. The recorded soup goes to mesh__from_soup (mesh.c) for the final checks
 *     and triangulation.
 * No exception leaves this file: mesh_load catches everything.
 */
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>
#include <mutex>
#include <new>
#include <vector>

#include <strings.h>
#include <sys/stat.h>

extern "C" {
#include "mesh_internal.h"
}

namespace {

struct mesh__traits : public OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
    typedef OpenMesh::Vec3d Normal;
};
typedef OpenMesh::PolyMesh_ArrayKernelT<mesh__traits> mesh__poly;
typedef OpenMesh::IO::ImporterT<mesh__poly> mesh__importer;

/* ImporterT that also records what the reader hands it (see the top of the
 * file for why). Vertices are recorded by handle in the order the reader
 * added them, which leaves out the copies ImporterT makes for non-manifold
 * faces. Normals are kept here rather than in the mesh so that a bad handle
 * from a reader cannot write out of bounds. */
class mesh__recorder : public mesh__importer {
public:
    explicit mesh__recorder(mesh__poly &m) : mesh__importer(m), mesh_(m) {}

    std::vector<int> verts;         /* reader's vertices, as handle indices */
    std::vector<size_t> start{0};   /* polygon f is idx[start[f] .. start[f+1]) */
    std::vector<int> idx;           /* handle indices */
    std::vector<double> normals;    /* 3 per handle index */
    std::vector<unsigned char> has_normal;
    size_t short_faces = 0;         /* fewer than 3 corners: not a polygon */

    using mesh__importer::add_face;
    using mesh__importer::set_normal;

    OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3f &p) override { return note(mesh__importer::add_vertex(p)); }
    OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3d &p) override { return note(mesh__importer::add_vertex(p)); }
    OpenMesh::VertexHandle add_vertex() override { return note(mesh__importer::add_vertex()); }

    OpenMesh::FaceHandle add_face(const VHandles &vs) override
    {
        if (vs.size() < 3) {
            short_faces++;
        } else {
            for (const auto &v : vs)
                idx.push_back(v.idx());
            start.push_back(idx.size());
        }
        return mesh__importer::add_face(vs);
    }

    void set_normal(OpenMesh::VertexHandle vh, const OpenMesh::Vec3f &n) override { keep(vh, n[0], n[1], n[2]); }
    void set_normal(OpenMesh::VertexHandle vh, const OpenMesh::Vec3d &n) override { keep(vh, n[0], n[1], n[2]); }

private:
    mesh__poly &mesh_;

    OpenMesh::VertexHandle note(OpenMesh::VertexHandle vh)
    {
        verts.push_back(vh.idx());
        return vh;
    }
    void keep(OpenMesh::VertexHandle vh, double x, double y, double z)
    {
        if (!vh.is_valid() || size_t(vh.idx()) >= mesh_.n_vertices())
            return;
        size_t i = size_t(vh.idx());
        if (has_normal.size() <= i) {
            has_normal.resize(mesh_.n_vertices(), 0);
            normals.resize(3 * mesh_.n_vertices(), 0.0);
        }
        normals[3 * i] = x;
        normals[3 * i + 1] = y;
        normals[3 * i + 2] = z;
        has_normal[i] = 1;
    }
};

/* A read-only seekable stream over the file's bytes (OpenMesh's OBJ reader
 * rewinds for its second pass; the PLY reader seeks to its binary data). */
class mesh__membuf : public std::streambuf {
public:
    mesh__membuf(const char *p, size_t n)
    {
        char *b = const_cast<char *>(p); /* only ever read: no put area */
        setg(b, b, b + n);
    }

protected:
    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override
    {
        char *base = dir == std::ios_base::beg ? eback() : dir == std::ios_base::cur ? gptr() : egptr();
        if (off < eback() - base || off > egptr() - base)
            return pos_type(off_type(-1));
        setg(eback(), base + off, egptr());
        return pos_type(gptr() - eback());
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode which) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, which);
    }
};

class mesh__nullbuf : public std::streambuf {
protected:
    int_type overflow(int_type c) override { return traits_type::not_eof(c); }
};

/* OpenMesh reports through its omerr/omlog streams and, in places, straight to
 * std::cerr; radray reports through rr_error, so both are silenced while a
 * file is read and restored afterwards. The lock also serialises use of
 * OpenMesh's reader singletons, whose state is not thread-safe. */
std::mutex mesh__lock;

class mesh__quiet {
public:
    mesh__quiet() : guard_(mesh__lock)
    {
        err_on_ = ::omerr().is_enabled();
        log_on_ = ::omlog().is_enabled();
        ::omerr().disable();
        ::omlog().disable();
        cerr_ = std::cerr.rdbuf(&null_);
    }
    ~mesh__quiet()
    {
        /* Flushing while disabled drops any half-written message. */
        ::omerr().flush();
        ::omlog().flush();
        if (err_on_)
            ::omerr().enable();
        if (log_on_)
            ::omlog().enable();
        std::cerr.rdbuf(cerr_);
    }
    mesh__quiet(const mesh__quiet &) = delete;
    mesh__quiet &operator=(const mesh__quiet &) = delete;

private:
    std::lock_guard<std::mutex> guard_;
    mesh__nullbuf null_;
    std::streambuf *cerr_;
    bool err_on_, log_on_;
};

const char *mesh__ext_name(mesh__format f)
{
    static const char *names[] = {".obj", ".ply", ".off", ".stl"};
    return names[f];
}

bool mesh__has_ext(const char *dot, const char *ext) { return dot && strcasecmp(dot, ext) == 0; }

/* Frees the pre-check's buffers however mesh__load returns. */
struct mesh__expect_guard {
    mesh__expect ex{};
    ~mesh__expect_guard() { mesh__expect_free(&ex); }
};

rr_status mesh__load(const char *path, mesh_tri **out, rr_error *err)
{
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(slash ? slash + 1 : path, '.');
    mesh__format fmt;
    if (mesh__has_ext(dot, ".obj"))
        fmt = MESH__OBJ;
    else if (mesh__has_ext(dot, ".ply"))
        fmt = MESH__PLY;
    else if (mesh__has_ext(dot, ".off"))
        fmt = MESH__OFF;
    else if (mesh__has_ext(dot, ".stl"))
        fmt = MESH__STL;
    else
        return mesh__fail(err, RR_ERR_INVALID, path, "unknown mesh format '%s' (expected .obj, .ply, .off or .stl)",
                          dot ? dot : "");

    struct stat st;
    if (stat(path, &st) != 0)
        return errno == ENOENT ? mesh__fail(err, RR_ERR_IO, path, "file does not exist")
                               : mesh__fail(err, RR_ERR_IO, path, "cannot open: %s", strerror(errno));
    if (!S_ISREG(st.st_mode)) /* a FIFO would block, a folder is no mesh */
        return mesh__fail(err, RR_ERR_IO, path, "not a regular file");
    char *raw = nullptr;
    size_t n = 0;
    if (rr_status s = rr_file_read_all(path, &raw, &n, err))
        return s;
    std::unique_ptr<char, void (*)(void *)> data(raw, free);
    if (n == 0)
        return mesh__fail(err, RR_ERR_IO, path, "empty file");

    mesh__expect_guard guard;
    mesh__expect &ex = guard.ex;
    if (rr_status s = mesh__check(path, fmt, raw, n, &ex, err))
        return s;

    mesh__poly mesh;
    mesh__recorder rec(mesh);
    OpenMesh::IO::Options opt = OpenMesh::IO::Options::VertexNormal;
    if (ex.binary)
        opt += OpenMesh::IO::Options::Binary;
    bool ok;
    {
        mesh__quiet quiet;
        mesh__membuf mb(ex.text ? ex.text : raw, ex.text ? ex.text_len : n);
        std::istream in(&mb);
        ok = OpenMesh::IO::IOManager().read(in, mesh__ext_name(fmt), rec, opt);
    }
    if (!ok)
        return mesh__fail(err, RR_ERR_PARSE, path, "OpenMesh could not read this %s file", mesh__ext_name(fmt) + 1);
    size_t nfaces = rec.start.size() - 1;
    if ((ex.nverts >= 0 && rec.verts.size() != size_t(ex.nverts)) ||
        (ex.nfaces >= 0 && nfaces + rec.short_faces != size_t(ex.nfaces)))
        return mesh__fail(err, RR_ERR_PARSE, path, "OpenMesh read %zu vertices and %zu faces, the file has %lld and %lld",
                          rec.verts.size(), nfaces, ex.nverts, ex.nfaces);

    /* Handle index -> position in the reader's vertex order. */
    const size_t nh = mesh.n_vertices();
    std::vector<uint32_t> remap(nh, UINT32_MAX);
    std::vector<double> pos(3 * rec.verts.size());
    for (size_t i = 0; i < rec.verts.size(); i++) {
        OpenMesh::VertexHandle vh(rec.verts[i]);
        if (!vh.is_valid() || size_t(rec.verts[i]) >= nh)
            return mesh__fail(err, RR_ERR_INTERNAL, path, "OpenMesh returned an invalid vertex handle");
        remap[size_t(rec.verts[i])] = uint32_t(i);
        const mesh__poly::Point &p = mesh.point(vh);
        pos[3 * i] = p[0];
        pos[3 * i + 1] = p[1];
        pos[3 * i + 2] = p[2];
    }
    if (ex.probe) {
        const double *a = &pos[0], *b = &pos[pos.size() - 3];
        for (int k = 0; k < 3; k++)
            if (float(a[k]) != ex.first[k] || float(b[k]) != ex.last[k])
                return mesh__fail(err, RR_ERR_PARSE, path, "OpenMesh misread the vertex data of this %s file",
                                  mesh__ext_name(fmt) + 1);
    }
    std::vector<uint32_t> idx(rec.idx.size());
    std::vector<unsigned char> used(rec.verts.size(), 0);
    for (size_t i = 0; i < rec.idx.size(); i++) {
        int h = rec.idx[i];
        if (h < 0 || size_t(h) >= nh || remap[size_t(h)] == UINT32_MAX)
            return mesh__fail(err, RR_ERR_PARSE, path, "a face refers to a vertex that does not exist");
        idx[i] = remap[size_t(h)];
        used[idx[i]] = 1;
    }

    /* Normals only when the file has them for every vertex a face uses. */
    std::vector<double> nrm;
    if (opt.vertex_has_normal() && !rec.has_normal.empty()) {
        nrm.assign(3 * rec.verts.size(), 0.0);
        for (size_t i = 0; i < rec.verts.size() && !nrm.empty(); i++) {
            size_t h = size_t(rec.verts[i]);
            if (h < rec.has_normal.size() && rec.has_normal[h]) {
                memcpy(&nrm[3 * i], &rec.normals[3 * h], 3 * sizeof(double));
            } else if (used[i]) {
                nrm.clear();
            } else {
                nrm[3 * i + 2] = 1.0; /* no triangle uses it: any unit vector will do */
            }
        }
    }

    mesh__soup soup;
    soup.pos = pos.data();
    soup.normals = nrm.empty() ? nullptr : nrm.data();
    soup.nverts = rec.verts.size();
    soup.start = rec.start.data();
    soup.idx = idx.data();
    soup.nfaces = nfaces;
    return mesh__from_soup(path, &soup, out, err);
}

} // namespace

extern "C" rr_status mesh_load(const char *path, mesh_tri **out, rr_error *err)
{
    if (!path || !out)
        return rr_error_set(err, RR_ERR_INVALID, "mesh_load: NULL argument");
    try {
        return mesh__load(path, out, err);
    } catch (const std::bad_alloc &) {
        return mesh__fail(err, RR_ERR_NOMEM, path, "out of memory");
    } catch (const std::exception &e) {
        return mesh__fail(err, RR_ERR_INTERNAL, path, "mesh reader failed: %s", e.what());
    } catch (...) {
        return mesh__fail(err, RR_ERR_INTERNAL, path, "mesh reader failed");
    }
}
