/* rt_solid.c - TEMPORARY: replaced by the CSG implementation (issue 6). */
#include "rt_internal.h"

rr_status rt__solids_build(const scene *s, struct rt_solid_accel **out, rr_error *err)
{
    (void)s, (void)err;
    *out = NULL;
    return RR_OK;
}
void rt__solids_destroy(struct rt_solid_accel *sa) { (void)sa; }
void rt_csg_spans(const scene *s, const rt_accel *a, uint32_t node, rr_ray ray, double tmin, double tmax, rt_spans *out)
{
    (void)s, (void)a, (void)node, (void)ray, (void)tmin, (void)tmax;
    out->n = 0;
}
void rt_solid_spans(const scene *s, const rt_accel *a, uint32_t obj, rr_ray ray, double tmin, double tmax, rt_spans *out)
{
    rt_csg_spans(s, a, s->objects[obj].csg_root, ray, tmin, tmax, out);
}
int rt_solid_closest(const scene *s, const rt_accel *a, uint32_t obj, rr_ray ray, double tmin, double tmax, rt_hit *hit)
{
    (void)s, (void)a, (void)obj, (void)ray, (void)tmin, (void)tmax, (void)hit;
    return 0;
}
int rt_csg_contains(const scene *s, const rt_accel *a, uint32_t node, rr_vec3 p)
{
    (void)s, (void)a, (void)node, (void)p;
    return 0;
}
rr_vec3 rt_csg_leaf_normal(const scene *s, uint32_t leaf, int32_t surface, rr_vec3 p)
{
    (void)s, (void)leaf, (void)surface, (void)p;
    return rr_v3(0, 0, 1);
}
