/* sd_image.c -- validate a binary table image in memory and bind a table to it in place.
 *
 * The layout (docs/table-image.md; written by shapedisplay/render/image.py) is little-endian.
 * Header fields are decoded byte by byte (any host); the code arrays, blocks and tile index are
 * used in place, which needs a little-endian host (every target of this runtime is one) and an
 * 8-byte aligned image. Every count and offset is checked against the image size, in 64-bit
 * arithmetic, before anything is read through it. No allocation; the work is O(image size)
 * once (the CRC and the finiteness of float codes), never per tick.
 */
#include <math.h>
#include <string.h>
#include "sd_runtime.h"
#include "sd_math.h"

#define MAX_CANVAS ((int64_t)16384 * 16384)   /* table.MAX_CANVAS_SAMPLES */
#define MAX_TILES (1L << 20)
#define ABSENT 0xFFFFFFFFu

uint32_t sd_crc32(const void *data, size_t n)
{
    const uint8_t *p = (const uint8_t *)data;
    uint32_t crc = 0xFFFFFFFFu;
    size_t i;
    int b;
    for (i = 0; i < n; i++) {
        crc ^= p[i];
        for (b = 0; b < 8; b++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

static uint32_t u32le(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int32_t i32le(const uint8_t *p)
{
    uint32_t u = u32le(p);
    return u <= 0x7FFFFFFFu ? (int32_t)u : (int32_t)(u - 0x80000000u) - 0x7FFFFFFF - 1;
}

/* A stored real the runtime can hold: finite, and within float range in the single-precision build. */
static int real_ok(double v)
{
#ifdef SD_SINGLE
    return isfinite(v) && fabs(v) <= (double)FLT_MAX;
#else
    return isfinite(v);
#endif
}

/* Every value an integer-coded channel decodes (offset + scale x code) lies within the range of
 * sd_real. The rule bounds the code type's whole range, 0 .. 255 or 0 .. 65535, not the codes
 * stored: O(1) instead of a pass over the codes, sound for any code the image holds, and the
 * rule of the Python reader (table.py, channel schema), so a table is refused by both or by
 * neither. The value is linear in the code, so its extremes are offset and offset + scale x top;
 * like Python, offset +/- scale x top is required in range. They are computed in double from the
 * scale and offset as the build holds them (float in the single-precision build: a product of two
 * floats is exact in double, and a double sum within float range rounds to a finite float), so
 * the decode in sd_real cannot overflow when these do not. Float codes are the values themselves
 * (scale and offset unused), bounded by the finiteness pass. */
static int decoded_ok(const sd_channel_t *ch, uint32_t dtype)
{
    double sc = (double)ch->scale, of = (double)ch->offset, top = dtype == SD_U8 ? 255.0 : 65535.0;
    if (dtype == SD_F32 || dtype == SD_F64) return 1;
    return real_ok(of + sc * top) && real_ok(of - sc * top);
}

static double f64le(const uint8_t *p)
{
    uint64_t u = (uint64_t)u32le(p) | (uint64_t)u32le(p + 4) << 32;
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

static int host_little_endian(void)
{
    const uint16_t one = 1;
    uint8_t b;
    memcpy(&b, &one, 1);
    return b == 1;
}

/* [off, off + len) inside the body (before the CRC) and past the header (of either version). */
static int in_body(uint64_t off, uint64_t len, uint64_t body, uint32_t header)
{
    return off >= header && off <= body && len <= body - off;
}

static int64_t i64le(const uint8_t *p)
{
    uint64_t u = (uint64_t)u32le(p) | (uint64_t)u32le(p + 4) << 32;
    return u <= 0x7FFFFFFFFFFFFFFFull ? (int64_t)u : -(int64_t)(~u) - 1;
}

/* A real of a reaction record: finite, within float range in the single build, and within +-lim. */
static int real_in(double v, double lim) { return real_ok(v) && fabs(v) <= lim; }

/* The reaction section (version 2, docs/table-image.md): n REACT_DEF records then n_keys REACT_KEY records,
 * little-endian, converted field by field into img->react (the first SD_MAX_REACTIVE) and img->react_keys.
 * Every value is checked so that a tick never meets a record it cannot play: counts and offsets against the
 * blocks and codes, reals finite and bounded. */
static int load_reactions(sd_image_t *img, const uint8_t *p, uint64_t body, uint32_t header, int64_t n_blocks,
                          int64_t n_values, const int32_t (*blocks)[5])
{
    uint64_t off = u32le(p + 560), n = u32le(p + 564), n_keys = u32le(p + 568), rec = 0, krec = 0;
    uint64_t i;
    const double lim = SD_POSITION_LIMIT_M;
#define SD_COUNT(kind, name) +8
    rec = 0 SD_FIELDS_REACT_DEF(SD_COUNT);
    krec = 0 SD_FIELDS_REACT_KEY(SD_COUNT);
#undef SD_COUNT
    if (u32le(p + 572) != 0) return SD_ERR_IMAGE_LAYOUT;
    if (n == 0 && n_keys == 0) return SD_OK;
    if (n > 65536u || n_keys > 65536u || (off & 7u) || !in_body(off, n * rec + n_keys * krec, body, header))
        return SD_ERR_IMAGE_LAYOUT;
    if (n_keys > SD_MAX_KEYS) return SD_ERR_IMAGE_LAYOUT;     /* the build holds SD_MAX_KEYS keyframes */
    for (i = 0; i < n_keys; i++) {
        const uint8_t *q = p + off + n * rec + i * krec;
        sd_react_key_t *k = &img->react_keys[i];
        double t = f64le(q), dx = f64le(q + 8), dy = f64le(q + 16);
        if (!(real_in(t, 1e9) && t >= 0.0 && real_in(dx, lim) && real_in(dy, lim))) return SD_ERR_IMAGE_VALUE;
        k->t = (sd_real)t;
        k->dx = (sd_real)dx;
        k->dy = (sd_real)dy;
    }
    for (i = 0; i < n; i++) {
        const uint8_t *q = p + off + i * rec;
        sd_react_def_t d;
        int64_t kind, r0, c0, nr, nc, po;
        double x0, y0, x1, y1, pn, rn;
        int k = 0;
        /* every field, in record order: integers as int64, reals as float64 */
#define SD_RD_I64(name) d.name = i64le(q + 8 * k++);
#define SD_RD_F64(name) if (!real_in(f64le(q + 8 * k), 1e9)) return SD_ERR_IMAGE_VALUE; \
        d.name = (sd_real)f64le(q + 8 * k++);
#define SD_RD(kind, name) SD_RD_##kind(name)
        SD_FIELDS_REACT_DEF(SD_RD)
#undef SD_RD
#undef SD_RD_F64
#undef SD_RD_I64
        kind = d.kind;
        x0 = f64le(q + 8 * 16);
        y0 = f64le(q + 8 * 17);
        x1 = f64le(q + 8 * 18);
        y1 = f64le(q + 8 * 19);
        pn = (double)d.press_n;
        rn = (double)d.release_n;
        if (kind < SD_REACT_NONE || kind > SD_REACT_SURFACE || d.widget < 0 || d.widget > 1000000) return SD_ERR_IMAGE_LAYOUT;
        if (!(fabs(x0) <= lim && fabs(y0) <= lim && fabs(x1) <= lim && fabs(y1) <= lim && x0 <= x1 && y0 <= y1))
            return SD_ERR_IMAGE_VALUE;
        if (!(pn >= 0.0 && pn <= 1e3 && rn >= 0.0 && (pn == 0.0 || rn < pn))) return SD_ERR_IMAGE_VALUE;
        if (!(d.click_gain >= SD_R(0.0) && d.click_gain <= SD_R(1.0) && d.click_hz > SD_R(0.0) && d.click_hz <= SD_R(1e5)
              && d.click_s >= SD_R(0.0) && d.click_s <= SD_R(10.0) && d.drop >= SD_R(0.0) && d.drop <= SD_R(1.0)
              && d.drop_s >= SD_R(0.0) && d.drop_s <= SD_R(10.0)))
            return SD_ERR_IMAGE_VALUE;
        if (kind == SD_REACT_TOGGLE) {
            int64_t b = d.block, rows, cols;
            if (b < 0 || b >= n_blocks || (d.state0 != 0 && d.state0 != 1)) return SD_ERR_IMAGE_LAYOUT;
            rows = blocks[b][2];
            cols = blocks[b][3];
            if (d.offset_a < 0 || d.offset_b < 0 || d.offset_a + rows * cols > n_values || d.offset_b + rows * cols > n_values)
                return SD_ERR_IMAGE_LAYOUT;
        }
        r0 = d.part_row0;
        c0 = d.part_col0;
        nr = d.part_rows;
        nc = d.part_cols;
        po = d.part_offset;
        if (nr != 0) {
            if (nr < 1 || nc < 1 || nr > 16384 || nc > 16384 || po < 0 || po + nr * nc > n_values
                || r0 < -16384 || r0 > 32768 || c0 < -16384 || c0 > 32768)
                return SD_ERR_IMAGE_LAYOUT;
            if (d.wrap != 0 && d.wrap != 1) return SD_ERR_IMAGE_LAYOUT;
            if (d.wrap && !(x1 > x0 && y1 >= y0)) return SD_ERR_IMAGE_VALUE;
        } else if (d.wrap != 0 || kind == SD_REACT_OBJECT || kind == SD_REACT_SLIDER) {
            return SD_ERR_IMAGE_LAYOUT;           /* these move a part */
        }
        if (!(fabs((double)d.vx) <= 1e3 && fabs((double)d.vy) <= 1e3 && d.loop_s >= SD_R(0.0))) return SD_ERR_IMAGE_VALUE;
        if (d.n_keys < 0 || d.key0 < 0 || d.key0 > (int64_t)n_keys || d.n_keys > (int64_t)n_keys - d.key0
            || (d.n_keys > 0 && (nr == 0 || d.wrap)))
            return SD_ERR_IMAGE_LAYOUT;
        if (d.n_keys > 0) {
            int64_t j;
            for (j = d.key0 + 1; j < d.key0 + d.n_keys; j++)
                if (img->react_keys[j].t < img->react_keys[j - 1].t) return SD_ERR_IMAGE_VALUE;
            if (d.loop_s > SD_R(0.0) && d.loop_s < img->react_keys[d.key0 + d.n_keys - 1].t) return SD_ERR_IMAGE_VALUE;
        }
        if (kind == SD_REACT_SLIDER) {
            if ((d.axis != 0 && d.axis != 1) || !(d.track_len > SD_R(0.0)) || !(d.thumb_r >= SD_R(0.0))
                || d.n_detents < 0 || d.n_detents > 1000 || (d.n_detents > 0 && !(d.detent_step > SD_R(0.0)))
                || !(d.value_step > SD_R(0.0) && d.value_step <= SD_R(1.0)) || !(fabs((double)d.track0) <= lim)
                || !(d.track_len <= SD_R(2.0) * (sd_real)lim) || !(fabs((double)d.thumb_c) <= lim)
                || !(fabs((double)d.cross_c) <= lim) || !(fabs((double)d.detent0) <= lim))
                return SD_ERR_IMAGE_VALUE;
        }
        if (i < SD_MAX_REACTIVE) img->react[i] = d;
    }
    img->react_total = (int32_t)n;
    img->table.n_react = (int32_t)(n < SD_MAX_REACTIVE ? n : SD_MAX_REACTIVE);
    img->table.react = img->react;
    img->table.n_react_keys = (int32_t)n_keys;
    img->table.react_keys = img->react_keys;
    return SD_OK;
}

int sd_image_load(sd_image_t *img, const void *data, size_t size)
{
    const uint8_t *p = (const uint8_t *)data;
    static const uint32_t width[4] = {1, 2, 4, 8};
    uint64_t body, blocks_off, start_off, list_off, meta_off, n_tiles, n_entries;
    int64_t rows, cols, n_blocks, n_values, tr, tc, ty, tx;
    const int32_t(*blocks)[5];
    const uint32_t *start, *list;
    int64_t b, longest = 0;
    uint32_t version, header;
    int s;
    if (!img || !data) return SD_ERR_ARG;
    memset(img, 0, sizeof *img);
    if (size < SD_IMAGE_HEADER_SIZE + 4 || size > (size_t)1 << 30) return SD_ERR_IMAGE_SIZE;
    if (memcmp(p, "SDTI", 4) != 0) return SD_ERR_IMAGE_MAGIC;
    version = (uint32_t)p[4] + 256u * p[5];
    if (version != 1 && version != SD_IMAGE_VERSION) return SD_ERR_IMAGE_VERSION;
    header = version == 1 ? SD_IMAGE_HEADER_SIZE : SD_IMAGE_HEADER_SIZE_V2;
    if (size < header + 4u) return SD_ERR_IMAGE_SIZE;
    if ((uint32_t)p[6] + 256u * p[7] != header || u32le(p + 8) != size) return SD_ERR_IMAGE_SIZE;
    if ((size & 3u) != 0) return SD_ERR_IMAGE_SIZE;
    body = size - 4;
    if (sd_crc32(p, (size_t)body) != u32le(p + body)) return SD_ERR_IMAGE_CRC;
    if (!host_little_endian()) return SD_ERR_IMAGE_ENDIAN;
    if (((uintptr_t)data & 7u) != 0) return SD_ERR_IMAGE_ALIGN;

    rows = i32le(p + 16);
    cols = i32le(p + 20);
    n_blocks = i32le(p + 24);
    n_values = i32le(p + 28);
    tr = i32le(p + 36);
    tc = i32le(p + 40);
    ty = i32le(p + 44);
    tx = i32le(p + 48);
    n_entries = (uint64_t)u32le(p + 56);
    if (rows < 1 || cols < 1 || rows * cols > MAX_CANVAS || n_blocks < 0 || n_values < 0) return SD_ERR_IMAGE_LAYOUT;
    if (tr < 1 || tc < 1 || ty != (rows + tr - 1) / tr || tx != (cols + tc - 1) / tc || ty * tx > MAX_TILES)
        return SD_ERR_IMAGE_LAYOUT;
    n_tiles = (uint64_t)(ty * tx);
    blocks_off = u32le(p + 544);
    start_off = u32le(p + 548);
    list_off = u32le(p + 552);
    meta_off = u32le(p + 556);
    img->meta_len = u32le(p + 60);
    if (!in_body(blocks_off, (uint64_t)n_blocks * 20u, body, header) || (blocks_off & 3u)
        || !in_body(start_off, (n_tiles + 1u) * 4u, body, header) || (start_off & 3u)
        || !in_body(list_off, n_entries * 4u, body, header) || (list_off & 3u)
        || !in_body(meta_off, img->meta_len, body, header))
        return SD_ERR_IMAGE_LAYOUT;
    blocks = (const int32_t(*)[5])(const void *)(p + blocks_off);
    start = (const uint32_t *)(const void *)(p + start_off);
    list = (const uint32_t *)(const void *)(p + list_off);
    for (b = 0; b < n_blocks; b++) {
        int64_t r0 = blocks[b][0], c0 = blocks[b][1], nr = blocks[b][2], nc = blocks[b][3], off = blocks[b][4];
        if (r0 < 0 || c0 < 0 || nr < 1 || nc < 1 || r0 + nr > rows || c0 + nc > cols || off < 0
            || off + nr * nc > n_values)
            return SD_ERR_IMAGE_LAYOUT;
    }
    if (start[0] != 0 || start[n_tiles] != n_entries) return SD_ERR_IMAGE_LAYOUT;
    for (b = 0; b < (int64_t)n_tiles; b++) {
        if (start[b + 1] < start[b]) return SD_ERR_IMAGE_LAYOUT;
        if ((int64_t)(start[b + 1] - start[b]) > longest) longest = start[b + 1] - start[b];
    }
    if (longest != i32le(p + 52)) return SD_ERR_IMAGE_LAYOUT;
    for (b = 0; b < (int64_t)n_entries; b++)
        if ((int64_t)list[b] >= n_blocks) return SD_ERR_IMAGE_LAYOUT;

    img->table.grid.rows = (int32_t)rows;
    img->table.grid.cols = (int32_t)cols;
    img->table.grid.dx = (sd_real)f64le(p + 64);
    img->table.grid.dy = (sd_real)f64le(p + 72);
    img->table.grid.x0 = (sd_real)f64le(p + 80);
    img->table.grid.y0 = (sd_real)f64le(p + 88);
    if (!(img->table.grid.dx > SD_R(0.0) && img->table.grid.dy > SD_R(0.0) && real_ok(f64le(p + 64))
          && real_ok(f64le(p + 72)) && real_ok(f64le(p + 80)) && real_ok(f64le(p + 88))))
        return SD_ERR_IMAGE_VALUE;
    /* spacing and origin within SD_POSITION_LIMIT_M (table.MAX_COORDINATE_M, the Python reader's rule): a
     * held cursor starts at the origin, and an origin of 7e30 m made the next tick's velocity inf in float */
    for (s = 0; s < 4; s++)
        if (!(fabs(f64le(p + 64 + 8 * s)) <= SD_POSITION_LIMIT_M)) return SD_ERR_IMAGE_RANGE;
    for (s = 0; s < SD_IMAGE_NPARAM; s++) {
        img->params[s] = f64le(p + 96 + 8 * s);
        if (!real_ok(img->params[s])) return SD_ERR_IMAGE_VALUE;
    }
    for (s = 0; s < SD_NSLOT; s++) {
        const uint8_t *d = p + 224 + 32 * s;
        uint32_t dtype = u32le(d), off = u32le(d + 4);
        sd_channel_t *ch = &img->ch[s];
        int64_t i;
        img->table.slot[s] = NULL;
        if (dtype == ABSENT) continue;
        if (dtype > SD_F64 || (off % width[dtype]) != 0
            || !in_body(off, (uint64_t)n_values * width[dtype], body, header))
            return SD_ERR_IMAGE_LAYOUT;
        ch->codes = p + off;
        ch->dtype = (int)dtype;
        ch->scale = (sd_real)f64le(d + 8);
        ch->offset = (sd_real)f64le(d + 16);
        ch->background = (sd_real)f64le(d + 24);
        if (!real_ok(f64le(d + 8)) || !real_ok(f64le(d + 16)) || !real_ok(f64le(d + 24))) return SD_ERR_IMAGE_VALUE;
        if (dtype == SD_F32) {
            for (i = 0; i < n_values; i++)
                if (!isfinite(((const float *)ch->codes)[i])) return SD_ERR_IMAGE_VALUE;
        } else if (dtype == SD_F64) {
            for (i = 0; i < n_values; i++)
                if (!real_ok(((const double *)ch->codes)[i])) return SD_ERR_IMAGE_VALUE;
        }
        if (!decoded_ok(ch, dtype)) return SD_ERR_IMAGE_RANGE;
        img->table.slot[s] = ch;
    }
    img->table.n_blocks = (int32_t)n_blocks;
    img->table.blocks = blocks;
    img->table.tile_rows = (int32_t)tr;
    img->table.tile_cols = (int32_t)tc;
    img->table.tiles_y = (int32_t)ty;
    img->table.tiles_x = (int32_t)tx;
    img->table.tile_start = start;
    img->table.tile_list = list;
    img->n_values = (int32_t)n_values;
    img->max_tile_blocks = (int32_t)longest;
    img->image_size = (uint32_t)size;
    img->meta = (const char *)(p + meta_off);
    if (version >= 2) {
        int rc = load_reactions(img, p, body, header, n_blocks, n_values, blocks);
        if (rc != SD_OK) {
            img->table.n_react = 0;
            return rc;
        }
    }
    return SD_OK;
}

size_t sd_image_size(void) { return sizeof(sd_image_t); }

void sd_image_config(const sd_image_t *img, sd_config_t *cfg)
{
    const double *q = img->params;
    memset(cfg, 0, sizeof *cfg);
    cfg->pad.mass = (sd_real)q[SD_IP_MASS];
    cfg->pad.stiffness = (sd_real)q[SD_IP_STIFFNESS];
    cfg->pad.damping = (sd_real)q[SD_IP_DAMPING];
    cfg->pad.burst_gain = (sd_real)q[SD_IP_BURST_GAIN];
    cfg->pad.max_stick_period = (sd_real)q[SD_IP_MAX_STICK];
    cfg->mu_s = (sd_real)q[SD_IP_MU_S];
    cfg->mu_k = (sd_real)q[SD_IP_MU_K];
    cfg->k_mu = (sd_real)q[SD_IP_K_MU];
    cfg->skin_target = (sd_real)q[SD_IP_SKIN_TARGET];
    cfg->tick_rate = (sd_real)q[SD_IP_TICK_RATE];
    cfg->audio_rate = (sd_real)q[SD_IP_AUDIO_RATE];
    cfg->carrier_hz = (sd_real)q[SD_IP_CARRIER];
    cfg->rise_s = (sd_real)q[SD_IP_RISE];
    cfg->decay_s = (sd_real)q[SD_IP_DECAY];
    cfg->normal_force_constant = (sd_real)q[SD_IP_NORMAL_FORCE];
    cfg->policy = SD_RETRIGGER;
    cfg->model = SD_MODEL_JUMP;
}
