/* The G-code lexer's fast path (prs3_post.readers.lexer._lex_text), in C (loaded with ctypes by
 * prs3_post.native).
 *
 * Reads the lines of the regular shape (the lexer module's docstring: upper-case words of the given
 * letters in their order, each at most once, separated by spaces, no comment) into one column per
 * letter, as the numpy path does, with the same rules (a test compares the two on generated blocks):
 * every byte allowed after the one before it (the lexer's _AFTER, followed word by word: read_line),
 * at most one point in a word, a point with a digit beside it, at most 15 digits, letters in order. A
 * line that breaks a rule is not read: its row is all NaN and the Python lexer reads it (or says
 * what is wrong).
 *
 * Values are bit-identical to Python's float() of the text: decimal_value (decimal.h, shared with
 * goto.c) of the digits read here.
 *
 * A line not read is also tried as the usual comment line: one comment in parentheses, with only
 * spaces and tabs around it, its text printable ASCII (no parenthesis, no tab). Its kind is then
 * LINE_COMMENT and its span the text's bytes without the spaces at either end (Python's strip() of
 * that text), so the reader makes its comment event without decoding or matching the line
 * (prs3_post.readers.lexer._line_kinds_numpy is the reference).
 *
 * The CAM readers' other passes over bytes and rows live here too: prs3_scan_text (a file's bytes
 * checked before reading), prs3_line_end (blocks of whole lines), prs3_fill_moves (the 3+2 reader's
 * bulk step) and prs3_rows_to_part (rows to the part frame); each has its numpy twin as reference.
 *
 * Plain C with no Python API: ctypes releases the GIL for the call (convert and verify read the next
 * chunk on a second thread, read_ahead). No state outside the call: two threads may lex at once.
 *
 * prs3_native_version() (render.c) covers this function too: raise it (and NATIVE_VERSION in
 * native.py) when its arguments change.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "decimal.h"

/* the byte codes of the lexer's table (_CODE_*): a letter of column c is LETTER + c */
enum { OTHER, DIGIT, MINUS, DOT, SPACE, NEWLINE, LETTER };

/* what a line is (the lexer's LINE_*): not read, read (the regular shape), one comment */
enum { LINE_OTHER, LINE_READ, LINE_COMMENT };

static void fill_nan(double *row, int64_t width) {
    for (int64_t c = 0; c < width; c++) row[c] = NAN;
}

/* The line from text[start] (up to its LF) as the usual comment line: [ \t]*([printable ASCII but
 * parentheses]*)[ \t]*; 1 and span[0:2] its text without the spaces at either end, else 0. */
static int comment_line(const uint8_t *text, int64_t start, int64_t *span) {
    int64_t pos = start;
    while (text[pos] == ' ' || text[pos] == '\t') pos++;
    if (text[pos] != '(') return 0;
    int64_t first = ++pos;
    while (text[pos] >= 0x20 && text[pos] <= 0x7e && text[pos] != '(' && text[pos] != ')') pos++;
    if (text[pos] != ')') return 0;                     /* a LF, a tab, another '(', a byte not ASCII... */
    int64_t stop = pos++;
    while (text[pos] == ' ' || text[pos] == '\t') pos++;
    if (text[pos] != '\n') return 0;
    while (first < stop && text[first] == ' ') first++;
    while (stop > first && text[stop - 1] == ' ') stop--;
    span[0] = first;
    span[1] = stop;
    return 1;
}

/* Line text[*pos] up to its LF, read word by word into row: 1 where it has the regular shape, else 0
 * (*pos then at the byte where it stopped being regular: the line's LF or before it). The rules of
 * the lexer's _AFTER (which byte may follow which), word by word: spaces between words (and at either
 * end); a word is a letter of a column (the columns in order, each once), an optional '-', digits
 * with at most one '.' among or after them (one digit at least, MAX_DIGITS at most), then a space,
 * the LF or the next word's letter. */
static inline int read_line(const uint8_t *text, int64_t *pos, const uint8_t *class_of, const uint8_t *codes,
                            double *row) {
    int64_t at = *pos;
    int last_rank = -1;
    for (;;) {
        int kind = class_of[text[at]];
        while (kind == SPACE) kind = class_of[text[++at]];
        if (kind == NEWLINE) break;
        if (kind != LETTER) goto irregular;
        int rank = codes[text[at]] - LETTER;
        if (rank <= last_rank) goto irregular;          /* repeated, or out of order */
        last_rank = rank;
        struct decimal number = DECIMAL_START;
        kind = class_of[text[++at]];
        if (kind == MINUS) {
            number.minus = 1;
            kind = class_of[text[++at]];
        }
        for (;;) {                                      /* digits, one point among or after them */
            if (kind == DIGIT) {
                if (!decimal_digit(&number, text[at])) goto irregular;
            } else if (kind != DOT || !decimal_point(&number)) {
                break;                                  /* (a second point: irregular below) */
            }
            kind = class_of[text[++at]];
        }
        /* a lonely point ("X.", "X-."), no number ("X", "X-"), or what may not follow a number */
        if (number.digits == 0 || !(kind == SPACE || kind == NEWLINE || kind == LETTER)) goto irregular;
        row[rank] = decimal_value(&number);
    }
    *pos = at;
    return 1;
irregular:
    *pos = at;
    return 0;
}

/* text[0:size]: lines each ending in LF (none where size is 0). codes: the lexer's 256-byte table of
 * byte codes for `width` letters (a code from LETTER + width on is taken as OTHER).
 * Writes, for the N lines: values (N, width) row-major, NaN where a line has no word of a letter and
 * on every line not read; kinds[k] the kind of line k (LINE_READ where it is read, LINE_COMMENT
 * where it is the usual comment line, else LINE_OTHER); ends (N + 1) where each line starts and,
 * last, size (line k is text[ends[k]:ends[k + 1] - 1], without its LF); spans (N, 2) the start and
 * stop in `text` of a LINE_COMMENT line's stripped text (other lines' rows are not written).
 * Returns N, or -1 (nothing promised about the outputs) when the text does not end with a LF or
 * N > rows (values, kinds and spans have room for `rows` lines, ends for rows + 1). */
int64_t prs3_lex_columns(const uint8_t *text, int64_t size, const uint8_t *codes, int64_t width, double *values,
                         uint8_t *kinds, int64_t *ends, int64_t rows, int64_t *spans) {
    if (size < 0 || (size > 0 && text[size - 1] != '\n') || width < 0 || rows < 0) return -1;
    uint8_t class_of[256];
    for (int b = 0; b < 256; b++) {
        int code = codes[b];
        class_of[b] = (uint8_t)(code < LETTER ? code : code < LETTER + width ? LETTER : OTHER);
    }
    int64_t n = 0;
    int64_t pos = 0;
    ends[0] = 0;
    while (pos < size) {                                /* one line: text[pos] up to its LF */
        if (n >= rows) return -1;
        double *row = values + n * width;
        int64_t line_start = pos;
        fill_nan(row, width);
        int bad = !read_line(text, &pos, class_of, codes, row);
        uint8_t line_kind = LINE_READ;
        if (bad) {
            fill_nan(row, width);
            line_kind = comment_line(text, line_start, spans + 2 * n) ? LINE_COMMENT : LINE_OTHER;
            const uint8_t *end = memchr(text + pos, '\n', (size_t)(size - pos));
            pos = end - text;                           /* found: the text ends with a LF */
        }
        kinds[n] = line_kind;
        ends[++n] = ++pos;                             /* the next line's start */
    }
    return n;
}

/* What prs3_scan_text finds in data[0:count] (next[k] is data[k + 1]), without a branch: its LFs, its
 * high bits, whether it has a control byte, whether a letter of a rotary word is followed by what may
 * follow one. A loop the compiler vectorizes where count is a constant (STRIDE). */
struct stride {
    int64_t lines;
    uint8_t high, control, rotary;
};
static inline struct stride scan_stride(const uint8_t *data, const uint8_t *next, int64_t count) {
    int64_t lines = 0;
    uint8_t high = 0, control = 0, rotary = 0;
    for (int64_t k = 0; k < count; k++) lines += data[k] == '\n';
    for (int64_t k = 0; k < count; k++) {
        uint8_t byte = data[k];
        high |= byte;
        control |= (uint8_t)((byte < 32) & (byte != '\t') & (byte != '\n') & (byte != '\r'));
        control |= (uint8_t)(byte == 127);
    }
    for (int64_t k = 0; k < count; k++) {
        /* a letter A B C a b c, then a space, a tab, '-', '.' or a digit ('-' to '9' but '/') */
        uint8_t letter = (uint8_t)((uint8_t)(data[k] | 0x20) - 'a');
        uint8_t after = next[k];
        uint8_t number = (uint8_t)(after - '-');
        uint8_t hit = (uint8_t)(-(letter < 3)) & (uint8_t)(-((number < 13) & (after != '/')) |
                                                           -(after == ' ') | -(after == '\t'));
        rotary |= hit;
    }
    return (struct stride){lines, high, control, rotary};
}

/* What the 3+2 G-code reader checks on every byte of a file before reading it, in one pass over
 * data[0:size] (prs3_post.readers.gcode._scan_bytes; _scan_bytes_numpy is the reference):
 *   found[0]: the offset of the first control byte (below 32 but TAB, LF, CR; or 127), else -1;
 *   found[1]: 1 where a byte is not ASCII (128 and up: UTF-8 to be checked by the decoder), else 0;
 *   found[2]: the LFs counted;
 *   found[3]: the offset of the first rotary hint, else -1: a letter A B C a b c, then spaces or tabs,
 *             an optional '-', spaces or tabs, and a digit or '.' (the 3+2 reader's _ROTARY_HINT).
 * Returns the LFs counted. */
int64_t prs3_scan_text(const uint8_t *data, int64_t size, int64_t *found) {
    enum { STRIDE = 4096 };
    int64_t control = -1, rotary = -1, lines = 0;
    uint8_t high = 0;
    for (int64_t start = 0; start < size; start += STRIDE) {
        /* a stride at a time; the exact places only in a stride that has a control byte or a rotary hint */
        int64_t stop = size - start > STRIDE ? start + STRIDE : size;
        /* the pairs (byte, next byte) up to the last byte but one: a rotary word has two bytes at least */
        int64_t pair_stop = stop < size - 1 ? stop : size - 1;
        struct stride seen = pair_stop - start == STRIDE ? scan_stride(data + start, data + start + 1, STRIDE)
                                                         : scan_stride(data + start, data + start + 1, pair_stop - start);
        if (pair_stop < stop) {                         /* the file's last byte */
            uint8_t last = data[size - 1];
            seen.lines += last == '\n';
            seen.high |= last;
            seen.control |= (uint8_t)(last < 32 ? last != '\t' && last != '\n' && last != '\r' : last == 127);
        }
        lines += seen.lines;
        high |= seen.high;
        for (int64_t k = start; seen.control && control < 0 && k < stop; k++) {
            uint8_t byte = data[k];
            if (byte < 32 ? byte != '\t' && byte != '\n' && byte != '\r' : byte == 127) control = k;
        }
        for (int64_t k = start; seen.rotary && rotary < 0 && k < pair_stop; k++) {
            if ((uint8_t)((data[k] | 0x20) - 'a') >= 3) continue;
            int64_t at = k + 1;
            while (at < size && (data[at] == ' ' || data[at] == '\t')) at++;
            if (at < size && data[at] == '-') at++;
            while (at < size && (data[at] == ' ' || data[at] == '\t')) at++;
            if (at < size && (data[at] == '.' || (data[at] >= '0' && data[at] <= '9'))) rotary = k;
        }
    }
    found[0] = control;
    found[1] = high >> 7;
    found[2] = lines;
    found[3] = rotary;
    return lines;
}

/* The offset just after the count-th LF of data[start:size] (count >= 1), or -1 - (the LFs there
 * are) when it has fewer: where a block of `count` whole lines from `start` ends. */
int64_t prs3_line_end(const uint8_t *data, int64_t size, int64_t start, int64_t count) {
    enum { STRIDE = 4096 };
    int64_t seen = 0, at = start < 0 ? 0 : start;
    while (size - at >= STRIDE) {                       /* whole strides counted (a loop the compiler vectorizes) */
        int64_t here = 0;
        for (int64_t k = at; k < at + STRIDE; k++) here += data[k] == '\n';
        if (seen + here >= count) break;                /* the count-th LF is in this stride */
        seen += here;
        at += STRIDE;
    }
    for (; at < size; at++) {
        if (data[at] == '\n' && ++seen == count) return at + 1;
    }
    return -1 - seen;
}

/* The 3+2 G-code reader's bulk step (prs3_post.readers.gcode._Reader.bulk; gcode._fill_moves_numpy is
 * the reference), one pass over the lines of a run:
 *   values (n, 6): the N G X Y Z F words of each line (NaN where absent), moves[k] 1 on the move lines
 *   (the others, blank or comments, have no word); state[5]: the modal motion (NaN: none yet), the F
 *   word (program units, NaN: none yet) and the position X Y Z (mm, NaN: unknown), updated to those
 *   after the run; limits[3]: mm per program unit, the least and the most feed (mm/min); codes[2]: the
 *   row kinds of a rapid and of a feed move; first: the line number of line 0.
 * Writes, for the m move lines: tip (m, 3) (mm, each axis as written times the scale, else as
 * before), kind (m), feed (m) (mm/min: the modal F times the scale; 0 for rapids), source (m) (line
 * numbers); words[2]: the G0 and G1 words. Returns m, or -1 where any line needs the careful reader
 * (a motion other than G0/G1 or none, F not > 0 or out of the limits, a feed move without F, a
 * position not finite): then the outputs and state are not to be used. */
int64_t prs3_fill_moves(const double *values, const uint8_t *moves, int64_t n, double *state, const double *limits,
                        const int64_t *codes, int64_t first, double *tip, int64_t *kind, double *feed,
                        int64_t *source, int64_t *words) {
    double motion = state[0], word = state[1], x = state[2], y = state[3], z = state[4];
    double scale = limits[0], least = limits[1], most = limits[2];
    int64_t m = 0, rapids = 0, feeds = 0;
    for (int64_t k = 0; k < n; k++) {
        if (!moves[k]) continue;
        const double *row = values + 6 * k;
        double g = row[1], f = row[5];
        if (!isnan(g)) {
            motion = g;
            rapids += g == 0.0;
            feeds += g == 1.0;
        }
        if (!(motion == 0.0 || motion == 1.0)) return -1;
        if (!isnan(f)) {
            double mm = f * scale;
            if (!(f > 0.0) || !(mm <= most) || !(mm >= least)) return -1;
            word = f;
        }
        if (!isnan(row[2])) x = row[2] * scale;
        if (!isnan(row[3])) y = row[3] * scale;
        if (!isnan(row[4])) z = row[4] * scale;
        if (!(isfinite(x) && isfinite(y) && isfinite(z))) return -1;
        double *point = tip + 3 * m;
        point[0] = x;
        point[1] = y;
        point[2] = z;
        if (motion == 1.0) {
            if (isnan(word)) return -1;
            kind[m] = codes[1];
            feed[m] = word * scale;
        } else {
            kind[m] = codes[0];
            feed[m] = 0.0;
        }
        source[m] = first + k;
        m++;
    }
    state[0] = motion;
    state[1] = word;
    state[2] = x;
    state[3] = y;
    state[4] = z;
    words[0] = rapids;
    words[1] = feeds;
    return m;
}

/* The CAM readers' rows to the part frame (prs3_post.workplane.WorkPlane.to_part, the reference):
 * out[i] = rotation @ rows[i] + origin, each element as rotate_rows makes it, ((x·r0 + y·r1) + z·r2)
 * + o, rounded after each operation (no fused multiply-add: the same bits as numpy's, whatever
 * the rows' count). rows and out (n, 3), rotation (3, 3) row-major, origin (3), or NULL: no origin
 * added (rotate_rows alone, for directions: adding 0 would turn -0 into 0). Returns n. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("fp-contract=off")))
#endif
int64_t prs3_rows_to_part(const double *rows, int64_t n, const double *rotation, const double *origin, double *out) {
    for (int64_t i = 0; i < n; i++) {
        double x = rows[3 * i], y = rows[3 * i + 1], z = rows[3 * i + 2];
        for (int j = 0; j < 3; j++) {
            const double *r = rotation + 3 * j;
            double turned = (x * r[0] + y * r[1]) + z * r[2];
            out[3 * i + j] = origin == NULL ? turned : turned + origin[j];
        }
    }
    return n;
}

/* The 3+2 G-code reader's sorting of a block's lines (prs3_post.readers.gcode._Reader.runs;
 * gcode._line_roles_numpy is the reference), from the lexer's values (n, 6: N G X Y Z F, NaN where
 * absent) and kinds: move[k] 1 where line k is read, its G (if any) is 0 or 1 and it has X, Y or Z (a
 * regular G0/G1 move); quiet[k] 1 where it is the usual comment line, or read without a word (blank).
 * Returns the moves counted. */
int64_t prs3_line_roles(const double *values, const uint8_t *kinds, int64_t n, uint8_t *move, uint8_t *quiet) {
    int64_t moves = 0;
    for (int64_t k = 0; k < n; k++) {
        const double *row = values + 6 * k;
        int read = kinds[k] == LINE_READ;
        double g = row[1];
        int axis = !isnan(row[2]) || !isnan(row[3]) || !isnan(row[4]);
        int is_move = read && (isnan(g) || g == 0.0 || g == 1.0) && axis;
        int blank = read && isnan(row[0]) && isnan(g) && !axis && isnan(row[5]);
        move[k] = (uint8_t)is_move;
        quiet[k] = (uint8_t)(kinds[k] == LINE_COMMENT || blank);
        moves += is_move;
    }
    return moves;
}
