/* test_scene_errors.c - the scene loader on bad input: every error names the
 * file, the JSON path (or line:column) and what was expected, and leaves the
 * output untouched. (Good scenes: test_scene.c.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "scene.h"
#include "test_scene_util.h"

static void overrides_bad(void **state)
{
    (void)state;
    static const struct {
        const char *ov;
        rr_status code;
        const char *want;
    } cases[] = {
        {"render.spp", RR_ERR_INVALID, "--set 'render.spp': expected KEY=VALUE"},
        {"=3", RR_ERR_INVALID, "--set '=3': the key before '=' is empty"},
        {"objects[5].material=red", RR_ERR_INVALID, "index 5 is out of range: objects has 1 item"},
        {"objects.material=red", RR_ERR_INVALID, "objects is not an object"},
        {"camera.w.x=1", RR_ERR_INVALID, "camera.w is not an object"},
        {"camera[0]=1", RR_ERR_INVALID, "camera is not an array"},
        {"objects[x]=1", RR_ERR_INVALID, "an array index must be a number in brackets"},
        {"objects[0=1", RR_ERR_INVALID, "missing ']'"},
        {"render..spp=1", RR_ERR_INVALID, "empty key"},
        {"lights[0].type=point", RR_ERR_INVALID, "lights does not exist, so it has no index 0"},
        /* Well-formed overrides are validated like the file. */
        {"render.spp=0", RR_ERR_INVALID, "bad.json: render.spp: must be an integer in [1, 16777216] (got 0)"},
        {"render.spq=2", RR_ERR_INVALID, "bad.json: render: unknown key 'spq'"},
        {"objects[0].material=blue", RR_ERR_INVALID, "bad.json: objects[0].material: unknown material 'blue'"},
        {"objects[0].vertices[0]=[nan,0,0]", RR_ERR_INVALID,
         "bad.json: objects[0].vertices[0]: expected an array of 3 numbers [x, y, z] (got the string \"[nan,0,0]\")"},
        {"format=radray-scene/2", RR_ERR_INVALID, "bad.json: format: expected \"radray-scene/1\""},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        scene_load_opts opts = {0};
        opts.overrides = &cases[i].ov;
        opts.noverrides = 1;
        expect_fail_opts(make_scene(NULL, NULL, "", NULL, ""), &opts, "", cases[i].code, cases[i].want);
    }
}

static void invalid_json(void **state)
{
    (void)state;
    static const struct {
        const char *text, *want;
    } cases[] = {
        /* Line 3, column 14 is the ',' where a key should be. */
        {"{\n  \"format\": \"radray-scene/1\",\n  \"camera\": {, \"w\": 1}\n}",
         "bad.json:3:14: invalid JSON near ', \"w\": 1}': expected a key in double quotes"},
        {"{\"format\": \"radray-scene/1\", \"camera\": {\"s\": NaN}}",
         "bad.json:1:46: invalid JSON near 'NaN}}': NaN and infinities are not JSON numbers"},
        {"{\"format\": \"radray-scene/1\",\n\"x\": Infinity}", "bad.json:2:6: invalid JSON near 'Infinity}'"},
        {"{\"x\": -Infinity}", "bad.json:1:7: invalid JSON near '-Infinity}'"},
        {"{\"format\": \"radray-scene/1\"} trailing",
         "bad.json:1:30: invalid JSON near 'trailing': unexpected text after the end of the JSON value"},
        {"{\"format\": \"radray-scene/1\",\n  \"camera\": {",
         "bad.json:2:14: invalid JSON at the end of the text: unexpected end of the text inside an object"},
        {"{\"a\": [1, 2,]}", "bad.json:1:13: invalid JSON near ']}': a comma before ']' (JSON allows no trailing comma)"},
        {"{\"a\": 1,\n}", "bad.json:2:1: invalid JSON near '}': a comma before '}' (JSON allows no trailing comma)"},
        {"{\"a\": 1 \"b\": 2}", "bad.json:1:9: invalid JSON near '\"b\": 2}': expected ',' or '}' after a value"},
        {"{'a': 1}", "bad.json:1:2: invalid JSON near ''a': 1}': strings and keys take double quotes"},
        {"{\"a\": \"abc\n\"}", "bad.json:1:11: invalid JSON at the end of the line: line break inside a string"},
        {"{\"a\": \"a\tb\"}", "bad.json:1:9: invalid JSON near '?b\"}': control character inside a string"},
        {"{\"a\": \"a\\qb\"}", "bad.json:1:9: invalid JSON near '\\qb\"}': invalid escape in a string"},
        {"{\"a\": 01}", "bad.json:1:7: invalid JSON near '01}': a number cannot have a leading zero"},
        {"{\"a\": 1.}", "bad.json:1:7: invalid JSON near '1.}': a number needs digits after '.'"},
        {"{\"a\": 1e}", "bad.json:1:7: invalid JSON near '1e}': a number needs digits in its exponent"},
        {"{\"a\": -}", "bad.json:1:7: invalid JSON near '-}': a number needs digits after '-'"},
        {"\xEF\xBB\xBF{\"a\": x}", "bad.json:1:10: invalid JSON near 'x}': expected a value"},
        {"{\"a\": \"abc", "bad.json:1:7: invalid JSON near '\"abc': unterminated string (it starts here)"},
        {"{\"a\": tru}", "bad.json:1:7: invalid JSON near 'tru}': expected a value"},
        {"{\"a\" 1}", "bad.json:1:6: invalid JSON near '1}': expected ':' after the key"},
        {"{\"a\": .5}", "bad.json:1:7: invalid JSON near '.5}': expected a value"},
        {"{\"a\": 1.00000000000000000000000000000000000000000000000000000000000000001}",
         "bad.json:1:7: invalid JSON near '1.0000000000000000000000': a number longer than 63 characters"},
        {"  \n ", "bad.json: the file is empty"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        expect_fail(cases[i].text, RR_ERR_PARSE, cases[i].want);
}

/* Every other kind of bad input: the message names the place. */
static void bad_inputs(void **state)
{
    (void)state;
#define TRI(extra) "[{\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[0,1,2]]" extra "}]"
#define OBJ1(body) "[{" body "}]"
    static const struct {
        const char *cam, *mats, *lights, *objs, *render, *raw;
        rr_status code;
        const char *want;
    } cases[] = {
        /* the file as a whole */
        {0, 0, 0, 0, 0, "[1, 2]", RR_ERR_INVALID, "bad.json: expected a JSON object with \"format\": \"radray-scene/1\" (got an array of 2 items)"},
        {0, 0, 0, 0, 0, "{\"camera\": {}}", RR_ERR_INVALID, "bad.json: format: missing (expected \"radray-scene/1\""},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/2\"}", RR_ERR_INVALID, "bad.json: format: expected \"radray-scene/1\" (got the string \"radray-scene/2\")"},
        {0, 0, 0, 0, 0, "{\"format\": 1}", RR_ERR_INVALID, "bad.json: format: expected \"radray-scene/1\" (got the number 1)"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"lihgts\": []}", RR_ERR_INVALID,
         "bad.json: unknown key 'lihgts' (allowed: format, name, description, camera, materials, lights, objects, render, radiosity, camera_path)"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"format\": \"radray-scene/1\"}", RR_ERR_INVALID, "bad.json: key 'format' appears twice"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"name\": 3}", RR_ERR_INVALID, "bad.json: name: expected a string (got the number 3)"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"description\": []}", RR_ERR_INVALID, "bad.json: description: expected a string"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"materials\": {\"a\": {}}, \"objects\": []}", RR_ERR_INVALID,
         "bad.json: camera: missing (expected an object"},
        /* camera */
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1,\"fov\":3}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: unknown key 'fov' (allowed: type, E, O, U, s, w, h)"},
        {"{\"type\":\"pinhole\"}", 0, 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: camera.type: expected \"lecture\" or \"lookat\" (got the string \"pinhole\")"},
        {"{\"E\":[0,0,5]}", 0, 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: camera.type: missing"},
        {"[]", 0, 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: camera: expected an object (got an array of 0 items)"},
        {"{\"type\":\"lecture\",\"E\":\"here\",\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.E: expected an array of 3 numbers [x, y, z] (got the string \"here\")"},
        {"{\"type\":\"lecture\",\"E\":[0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.E: expected an array of 3 numbers [x, y, z] (got an array of 2 items)"},
        {"{\"type\":\"lecture\",\"E\":[0,null,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.E[1]: expected a number (got null)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.O: missing (expected an array of 3 numbers [x, y, z])"},
        {"{\"type\":\"lecture\",\"E\":[0,0,1e999],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.E[2]: the number is out of range (it overflows a double to infinity)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":-3,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.w: must be an integer in [0, 1073741823] (got -3)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1.5}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.h: expected an integer (got 1.5)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.s: the pixel scale must be > 0 (got 0)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,0,-2],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: the up vector U is parallel to the view direction"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,5],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: the screen centre O equals the viewpoint E"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":180,\"width\":4,\"height\":4}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.fov: must be in (0, 180) degrees (got 180)"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":60,\"width\":-4,\"height\":4}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.width: must be an integer in [1, 2147483647] (got -4)"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":60,\"width\":4}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.height: missing (expected an integer)"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":60,\"width\":4,\"height\":4,\"s\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: unknown key 's' (allowed: type, eye, target, up, fov, width, height)"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1e-30,-1],\"fov\":60,\"width\":4,\"height\":4}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: the up vector U is parallel to the view direction"},
        /* materials */
        {0, "[]", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials: expected an object mapping names to materials (got an array of 0 items)"},
        /* no materials at all is allowed (models bring theirs): an object that names one is the error */
        {0, "{}", 0, 0, 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].material: unknown material 'white' (the scene has no \"materials\")"},
        {0, "{\"white\":{\"difuse\":0.5}}", 0, 0, 0, 0, RR_ERR_INVALID,
         "bad.json: materials.white: unknown key 'difuse' (allowed: diffuse, ambient, specular, k, mirror, emission)"},
        {0, "{\"white\":{\"diffuse\":[1.5,0,0]}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.diffuse[0]: must be in [0, 1] (got 1.5)"},
        {0, "{\"white\":{\"diffuse\":2}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.diffuse: must be in [0, 1] (got 2)"},
        {0, "{\"white\":{\"diffuse\":[0.5,0.5]}}", 0, 0, 0, 0, RR_ERR_INVALID,
         "bad.json: materials.white.diffuse: expected a number or an array of 3 numbers [r, g, b] (got an array of 2 items)"},
        {0, "{\"white\":{\"mirror\":[0,0,1.1]}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.mirror[2]: must be in [0, 1] (got 1.1)"},
        {0, "{\"white\":{\"emission\":[0,0,-1]}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.emission[2]: must be >= 0 (got -1)"},
        {0, "{\"white\":{\"diffuse\":[0.5,0.6,0.5],\"mirror\":[0.4,0.5,0.4]}}", 0, 0, 0, 0, RR_ERR_INVALID,
         "bad.json: materials.white: diffuse + mirror reflectance is 1.1 in channel G: a surface cannot reflect more than it receives (at most 1)"},
        {0, 0, "[{\"type\":\"point\",\"position\":[0,0,1],\"intensity\":[1,-2,1]}]", 0, 0, 0, RR_ERR_INVALID,
         "bad.json: lights[0].intensity[1]: must be >= 0 (got -2)"},
        {0, "{\"white\":{\"specular\":-0.5}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.specular: must be >= 0 (got -0.5)"},
        {0, "{\"white\":{\"ambient\":-1}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.ambient: must be >= 0 (got -1)"},
        {0, "{\"white\":{\"k\":-1}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.k: must be >= 0 (got -1)"},
        {0, "{\"white\":{\"k\":\"high\"}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.k: expected a number (got the string \"high\")"},
        {0, "{\"white\":3}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white: expected an object (got the number 3)"},
        {0, "{\"white\":{},\"white\":{}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white: material 'white' is defined twice"},
        {0, "{\"\":{}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials: a material name is empty"},
        {0, "{\"a234567890123456789012345678901234567890123456789012345678901234\":{}}", 0, 0, 0, 0, RR_ERR_INVALID,
         "the material name is too long (64 bytes, at most 63)"},
        /* lights */
        {0, 0, "{}", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights: expected an array of lights (got an object)"},
        {0, 0, "[{\"type\":\"spot\",\"intensity\":1}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].type: expected \"directional\" or \"point\" (got the string \"spot\")"},
        {0, 0, "[{\"intensity\":1}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].type: missing"},
        {0, 0, "[{\"type\":\"directional\",\"direction\":[0,0,0],\"intensity\":1}]", 0, 0, 0, RR_ERR_INVALID,
         "bad.json: lights[0].direction: the direction is the zero vector"},
        {0, 0, "[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1},{\"type\":\"point\",\"direction\":[0,0,1],\"intensity\":1}]", 0, 0, 0,
         RR_ERR_INVALID, "bad.json: lights[1]: unknown key 'direction' (allowed: type, name, position, intensity)"},
        {0, 0, "[{\"type\":\"point\",\"position\":[0,0,0]}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].intensity: missing"},
        {0, 0, "[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":-2}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].intensity: must be >= 0 (got -2)"},
        {0, 0, "[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1,\"name\":7}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].name: expected a string"},
        /* objects */
        {0, 0, 0, "{}", 0, 0, RR_ERR_INVALID, "bad.json: objects: expected an array of objects (got an object)"},
        {0, 0, 0, "[]", 0, 0, RR_ERR_INVALID, "bad.json: objects: expected at least one object"},
        {0, 0, 0, "[3]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0]: expected an object (got the number 3)"},
        {0, 0, 0, OBJ1("\"material\":\"white\""), 0, 0, RR_ERR_INVALID, "bad.json: objects[0].type: missing"},
        {0, 0, 0, OBJ1("\"type\":\"cube\",\"material\":\"white\""), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].type: unknown type 'cube' (known: mesh, triangles, quad, box, sphere, quadric, csg, model)"},
        /* solids in detail: test_scene_csg.c */
        {0, 0, 0, "[" QUAD("white") "},{\"type\":\"csg\",\"material\":\"white\"}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[1].op: missing (expected one of union, intersection, difference)"},
        {0, 0, 0, OBJ1("\"type\":\"quadric\",\"material\":\"white\""), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].shape: missing (expected one of ellipsoid, cylinder, cone, paraboloid, hyperboloid, general)"},
        {0, 0, 0, "[" QUAD("white") ",\"colour\":\"red\"}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0]: unknown key 'colour' (allowed: type, name, material, transform, cull, vertices, flip)"},
        {0, 0, 0, "[" QUAD("white") ",\"material\":\"red\"}]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0]: key 'material' appears twice"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].material: missing (expected the name of a material)"},
        {0, "{\"white\":{},\"red\":{},\"green\":{}}", 0, "[" QUAD("white") "}," QUAD("blue") "}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[1].material: unknown material 'blue' (known: white, red, green)"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":3,\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].material: expected the name of a material (got the number 3)"},
        {0, 0, 0, "[" QUAD("white") ",\"cull\":\"yes\"}]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0].cull: expected true, false or \"auto\" (got the string \"yes\")"},
        {0, 0, 0, "[" QUAD("white") ",\"name\":\"\"}]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0].name: expected a non-empty string"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].vertices: expected an array of 4 points [x, y, z] (got an array of 3 items)"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\""), 0, 0, RR_ERR_INVALID, "bad.json: objects[0].vertices: missing"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[1,1e999,0],[0,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].vertices[2][1]: the number is out of range (it overflows a double to infinity)"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[-1e999,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].vertices[3][0]: the number is out of range (it overflows a double to -infinity)"},
        {0, 0, 0, TRI(",\"indices\":[[0,1,2]]"), 0, 0, RR_ERR_INVALID, "bad.json: objects[0]: key 'indices' appears twice"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[0,1,2],[0,2,3]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices[1][2]: vertex index 3 is out of range (the object has 3 vertices, 0..2)"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[-1,1,2]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices[0][0]: vertex index -1 is out of range"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[0,1.5,2]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices[0][1]: expected an integer (got 1.5)"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[0,1]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices[0]: expected a triangle [i, j, k] of 3 vertex indices (got an array of 2 items)"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices: expected an array of triangles"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices: missing"},
        {0, 0, 0, OBJ1("\"type\":\"box\",\"material\":\"white\",\"min\":[0,0,0],\"max\":[1,0,1]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].max: must be greater than min on every axis"},
        {0, 0, 0, OBJ1("\"type\":\"box\",\"material\":\"white\",\"max\":[1,1,1]"), 0, 0, RR_ERR_INVALID, "bad.json: objects[0].min: missing"},
        {0, 0, 0, OBJ1("\"type\":\"box\",\"material\":\"white\",\"min\":[0,0,0],\"max\":[1,1,1],\"radius\":1"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0]: unknown key 'radius' (allowed: type, name, material, transform, cull, min, max, flip)"},
        {0, 0, 0, OBJ1("\"type\":\"sphere\",\"material\":\"white\",\"center\":[0,0,0],\"radius\":0"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].radius: must be > 0 (got 0)"},
        {0, 0, 0, OBJ1("\"type\":\"sphere\",\"material\":\"white\",\"center\":[0,0,0],\"radius\":1,\"transform\":[{\"scale\":[1,2,1]}]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].transform: a sphere takes only rotations, translations and uniform scales; "
                         "non-uniform scale (or shear) of a sphere needs the quadric type"},
        {0, 0, 0, OBJ1("\"type\":\"mesh\",\"material\":\"white\""), 0, 0, RR_ERR_INVALID, "bad.json: objects[0].file: missing (expected a string)"},
        {0, 0, 0, OBJ1("\"type\":\"mesh\",\"material\":\"white\",\"file\":\"x.obj\",\"flip\":1"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].flip: expected true or false (got the number 1)"},
        {0, 0, 0, OBJ1("\"type\":\"mesh\",\"material\":\"white\",\"file\":\"x.obj\",\"indices\":[]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0]: unknown key 'indices' (allowed: type, name, material, transform, cull, file, flip)"},
        /* transforms */
        {0, 0, 0, "[" QUAD("white") ",\"transform\":{\"scale\":2}}]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0].transform: expected an array of steps"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"scale\":[1,0,1]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].scale: a zero scale flattens the object"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"translate\":[1,0,0]},{\"scale\":2,\"translate\":[1,0,0]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[1]: expected exactly one of translate, scale, rotate, matrix (got 2 keys)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"shear\":2}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0]: unknown key 'shear' (allowed: translate, scale, rotate, matrix)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0]: expected exactly one of translate, scale, rotate, matrix (got 0 keys)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"rotate\":{\"axis\":[0,0,0],\"degrees\":5}}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].rotate.axis: the rotation axis is the zero vector"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"rotate\":{\"axis\":[0,0,1]}}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].rotate.degrees: missing (expected a number)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"rotate\":{\"axis\":[0,0,1],\"degrees\":5,\"angle\":1}}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].rotate: unknown key 'angle' (allowed: axis, degrees)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"translate\":[0,0,\"1\"]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].translate[2]: expected a number (got the string \"1\")"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"matrix\":[[1,0,0,0],[0,1,0],[0,0,1,0]]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].matrix[1]: expected a row of 4 numbers (got an array of 3 items)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"matrix\":[[1,0,0,0],[0,1,0,0],[1,1,0,0]]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform: the transform is singular (determinant 0): it flattens the object"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"scale\":1e200},{\"scale\":1e200}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform: the combined transform overflows (it is not finite)"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[1e300,0,0],[1,1,0],[0,1,0]],\"transform\":[{\"scale\":1e10}]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0]: vertex 1 is not finite after the transform"},
        /* render */
        {0, 0, 0, 0, "[]", 0, RR_ERR_INVALID, "bad.json: render: expected an object (got an array of 0 items)"},
        {0, 0, 0, 0, "{\"sp\":4}", 0, RR_ERR_INVALID,
         "bad.json: render: unknown key 'sp' (allowed: spp, seed, max_depth, threads, exposure, background, ambient, light_samples, half_float)"},
        {0, 0, 0, 0, "{\"spp\":0}", 0, RR_ERR_INVALID, "bad.json: render.spp: must be an integer in [1, 16777216] (got 0)"},
        {0, 0, 0, 0, "{\"spp\":2.5}", 0, RR_ERR_INVALID, "bad.json: render.spp: expected an integer (got 2.5)"},
        {0, 0, 0, 0, "{\"spp\":\"4\"}", 0, RR_ERR_INVALID, "bad.json: render.spp: expected an integer (got the string \"4\")"},
        {0, 0, 0, 0, "{\"spp\":1e999}", 0, RR_ERR_INVALID, "bad.json: render.spp: expected an integer in [1, 16777216] (got a number too large to be exact)"},
        {0, 0, 0, 0, "{\"seed\":-1}", 0, RR_ERR_INVALID, "bad.json: render.seed: must be an integer in [0, 9007199254740992] (got -1)"},
        {0, 0, 0, 0, "{\"max_depth\":-1}", 0, RR_ERR_INVALID, "bad.json: render.max_depth: must be an integer in [0, 1000] (got -1)"},
        {0, 0, 0, 0, "{\"threads\":100000}", 0, RR_ERR_INVALID, "bad.json: render.threads: must be an integer in [0, 4096] (got 100000)"},
        {0, 0, 0, 0, "{\"light_samples\":0}", 0, RR_ERR_INVALID, "bad.json: render.light_samples: must be an integer in [1, 65536] (got 0)"},
        {0, 0, 0, 0, "{\"exposure\":\"bright\"}", 0, RR_ERR_INVALID, "bad.json: render.exposure: expected a number (got the string \"bright\")"},
        {0, 0, 0, 0, "{\"background\":[-0.5,0,0]}", 0, RR_ERR_INVALID, "bad.json: render.background[0]: must be >= 0 (got -0.5)"},
        {0, 0, 0, 0, "{\"ambient\":true}", 0, RR_ERR_INVALID, "bad.json: render.ambient: expected a number or an array of 3 numbers [r, g, b] (got true)"},
        {0, 0, 0, 0, "{\"half_float\":1}", 0, RR_ERR_INVALID, "bad.json: render.half_float: expected true or false (got the number 1)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *json = cases[i].raw ? cases[i].raw
                                        : make_scene(cases[i].cam, cases[i].mats, cases[i].lights ? cases[i].lights : "",
                                                     cases[i].objs, cases[i].render ? cases[i].render : "");
        expect_fail(json, cases[i].code, cases[i].want);
    }
#undef TRI
#undef OBJ1
}

/* Hostile values that used to pass: derived view quantities that overflow,
 * vectors whose length overflows or underflows, and strings that are not
 * text (invalid UTF-8, a NUL escape, lone surrogates). */
static void hostile_values(void **state)
{
    (void)state;
    /* s * w overflows: refused (it was a NaN ray and SIGSEGV in the BVH walk). */
    expect_fail(make_scene("{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":1e306,\"w\":255,"
                           "\"h\":255}",
                           NULL, "", NULL, NULL),
                RR_ERR_INVALID, "rays are not finite");
    /* A valid up vector with large or tiny components is fine. */
    const char *ups[] = {"[0,1e300,0]", "[0,1e-300,0]", "[1e-200,1e200,0]"};
    for (int i = 0; i < 3; i++) {
        char cam[256];
        snprintf(cam, sizeof cam,
                 "{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":%s,\"s\":0.5,\"w\":2,\"h\":1}", ups[i]);
        scene *sc = load_ok(make_scene(cam, NULL, "", NULL, NULL), NULL);
        assert_v3(sc->view.J, 0, 1, 0);
        scene_destroy(sc);
    }
    /* A light direction whose length overflows is still a direction. */
    scene *sc = load_ok(make_scene(NULL, NULL,
                                   "[{\"type\":\"directional\",\"direction\":[1e308,1e308,0],\"intensity\":1}]",
                                   NULL, NULL),
                        NULL);
    assert_v3(sc->lights[0].direction, sqrt(0.5), sqrt(0.5), 0);
    scene_destroy(sc);
    /* Strings. */
    expect_fail(make_scene(NULL, NULL, "", "[" QUAD("white") ",\"name\":\"a\xff\"}]", NULL), RR_ERR_PARSE,
                "invalid UTF-8");
    expect_fail(make_scene(NULL, NULL, "", "[" QUAD("white") ",\"name\":\"a\xc0\xaf\"}]", NULL), RR_ERR_PARSE,
                "invalid UTF-8"); /* an overlong '/' */
    expect_fail(make_scene(NULL, NULL, "", "[{\"type\":\"quad\",\"material\":\"white\\u0000junk\",\"vertices\":"
                                           "[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]",
                           NULL),
                RR_ERR_PARSE, "\\u0000");
    expect_fail(make_scene(NULL, NULL, "", "[" QUAD("white") ",\"name\":\"x\\ud800y\"}]", NULL), RR_ERR_PARSE,
                "lone high surrogate");
    expect_fail(make_scene(NULL, NULL, "", "[" QUAD("white") ",\"name\":\"x\\udc00\"}]", NULL), RR_ERR_PARSE,
                "lone low surrogate");
    /* Real text loads: UTF-8 and a surrogate pair. */
    sc = load_ok(make_scene(NULL, NULL, "", "[" QUAD("white") ",\"name\":\"c\xc3\xb6rnell \\ud83d\\ude00\"}]", NULL),
                 NULL);
    assert_string_equal(sc->objects[0].name, "c\xc3\xb6rnell \xf0\x9f\x98\x80");
    scene_destroy(sc);
}

static void resolution_limits(void **state)
{
    (void)state;
    /* 2000001 x 2000001 pixels: about 357 TiB of film. */
    expect_fail(make_scene("{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":1000000,\"h\":1000000}",
                           NULL, "", NULL, ""),
                RR_ERR_LIMIT, "bad.json: camera: a 2000001 x 2000001 image needs 349 TiB of film, over the limit of");
    /* So large that the byte count overflows size_t. */
    expect_fail(make_scene("{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":60,"
                           "\"width\":2147483647,\"height\":2147483647}",
                           NULL, "", NULL, ""),
                RR_ERR_LIMIT, "bad.json: camera: a 2147483647 x 2147483647 image needs");
    /* The caller's limit: 5 x 3 pixels need 5*3*12*8 = 1440 bytes. */
    scene_load_opts opts = {0};
    opts.max_image_bytes = 1439;
    expect_fail_opts(make_scene(NULL, NULL, "", NULL, ""), &opts, "", RR_ERR_LIMIT,
                     "bad.json: camera: a 5 x 3 image needs 1.4 KiB of film, over the limit of 1.4 KiB");
    opts.max_image_bytes = 1440;
    scene_destroy(load_ok(make_scene(NULL, NULL, "", NULL, ""), &opts));
}

static void missing_scene_file(void **state)
{
    (void)state;
    scene *s = NULL;
    rr_error err = {0};
    assert_int_equal(scene_load("/nonexistent/dir/x.json", NULL, &s, &err), RR_ERR_IO);
    assert_null(s);
    assert_non_null(strstr(err.msg, "/nonexistent/dir/x.json"));
}

static void write_file(const char *path, const char *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

static void bad_mesh_files(void **state)
{
    (void)state;
    char dir[] = "/tmp/radray-test-scene-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char p_empty[512], p_garbage[512], p_scene[512];
    snprintf(p_empty, sizeof p_empty, "%s/empty.obj", dir);
    snprintf(p_garbage, sizeof p_garbage, "%s/garbage.ply", dir);
    snprintf(p_scene, sizeof p_scene, "%s/nul.json", dir);
    write_file(p_empty, "", 0);
    static const char garbage[] = "ply\nformat binary_little_endian 1.0\nelement vertex 1000000\n"
                                  "property float x\nproperty float y\nproperty float z\nend_header\n\x01\x02\x03";
    write_file(p_garbage, garbage, sizeof garbage - 1);
    write_file(p_scene, "{\"format\": \"radray-scene/1\"}\0junk", 34);

    static const char *const files[] = {"missing.obj", "empty.obj", "garbage.ply"};
    for (size_t i = 0; i < 3; i++) {
        char objs[512], want[1024];
        snprintf(objs, sizeof objs, "[" QUAD("white") "},{\"type\":\"mesh\",\"material\":\"white\",\"file\":\"%s\"}]",
                 files[i]);
        /* mesh_load's own message, which names the file, after the scene's place. */
        snprintf(want, sizeof want, "bad.json: objects[1].file: %s/%s", dir, files[i]);
        scene *sentinel = (scene *)(uintptr_t)0x1234, *s = sentinel;
        rr_error err = {0};
        rr_status st = scene_load_string(make_scene(NULL, NULL, "", objs, ""), "bad.json", dir, NULL, &s, &err);
        assert_int_not_equal(st, RR_OK);
        assert_ptr_equal(s, sentinel);
        if (strncmp(err.msg, want, strlen(want)) != 0)
            fail_msg("message \"%s\" does not start with \"%s\"", err.msg, want);
    }
    /* A NUL byte in a scene file is refused, not silently cut. */
    scene *s = NULL;
    rr_error err = {0};
    assert_int_equal(scene_load(p_scene, NULL, &s, &err), RR_ERR_PARSE);
    assert_null(s);
    assert_non_null(strstr(err.msg, "NUL byte at offset 28"));

    unlink(p_empty);
    unlink(p_garbage);
    unlink(p_scene);
    rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(overrides_bad),
        cmocka_unit_test(invalid_json),
        cmocka_unit_test(bad_inputs),
        cmocka_unit_test(hostile_values),
        cmocka_unit_test(resolution_limits),
        cmocka_unit_test(missing_scene_file),
        cmocka_unit_test(bad_mesh_files),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
