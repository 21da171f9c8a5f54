/* Fast path of the mtcomp G-code reader and writer (see _fast.py).
 *
 * Handles only "simple" lines, exactly as mtcomp.toolpaths.gcode.ModalState would: lines made of
 * comments, the words N, G0/G1, F and the machine's axis words (each at most once) and words that
 * do not touch the geometry (M S ..., kept as written; a value word D E H L P Q, which the dialect
 * may refuse where no code of its block uses it, and T and O go to Python). Any other line (G codes
 * other than G0/G1, arcs, '%', errors of any kind) is handed back to Python (status FALLBACK) before the state is touched,
 * so Python interprets it (and raises the errors). Positions, directions and the formatting of
 * numbers reproduce the Python code bit for bit; tests compare both paths.
 *
 * state (double[26]): 0..5 position (mm, rad, per column), 6..11 dirs (+-1, 0 not known), 12 feed (mm/min),
 * 13 motion (-1 none, 0..3), 14 inch, 15 incremental, 16 lines done, 17 output is absolute,
 * 18 separator is CRLF, 19 Python takes every line (drilling cycle or G93 in force), 20 bit mask of
 * the axes whose position the program has given, 21 frame code (work offset, tool length number),
 * 22 motion word in force in the output (-1 unknown, 0, 1), 23 lines written with axis words they
 * did not name, 24 the first of them (0: none), 25 the dialect reads an axis word without a decimal
 * point in the least input increment (1 fanuc, 2 haas: such a word other than zero goes to
 * Python, on haas an F without a point too).
 * last (double[na]): per axis the position last written (mm, rad, read back from its text; NaN:
 * none yet). A coordinate is written when its text differs from the text of that value.
 *
 * Motion lines are written as writer.format_motion_lines does: the source line with the numbers of
 * its named axes replaced in place where their value changes (at least the word's decimals, and 4,
 * 5 in inch), G90 and the motion word put after the N word where the output needs them, the axes
 * the line does not name whose text changes (never an axis not known) added after its last axis
 * word in the line's letter case; later pieces of a split block are new lines, written only if they
 * change a coordinate. A line whose axis word has more than 15 decimals goes to Python.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { NEED_INPUT = 0, FALLBACK = 1, ROWS_FULL = 2, NEED_CORR = 3, OUT_FULL = 4, MISMATCH = 5 };

static const double POW10[23] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
                                 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static int is_alpha(char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'); }
static int is_digit(char c) { return c >= '0' && c <= '9'; }
/* A number with a zero before another digit (0019685, -05): fixed format (word_use.py). */
static int leading_zero(const char *p, const char *e) {
    if (p < e && (*p == '+' || *p == '-')) p++;
    return p + 1 < e && *p == '0' && is_digit(p[1]);
}

/* The number pattern of the Python tokenizer: [+-]?(\d+\.?\d*|\.\d+). 1 if found. */
static int parse_num(const char *p, const char *e, double *out, const char **next) {
    const char *s = p;
    int neg = 0;
    if (p < e && (*p == '+' || *p == '-')) { neg = (*p == '-'); p++; }
    uint64_t mant = 0;
    int ndig = 0, nint = 0, nfrac = 0;
    while (p < e && is_digit(*p)) { mant = mant * 10 + (uint64_t)(*p - '0'); ndig++; nint++; p++; }
    if (p < e && *p == '.') {
        p++;
        while (p < e && is_digit(*p)) { mant = mant * 10 + (uint64_t)(*p - '0'); ndig++; nfrac++; p++; }
    }
    if (nint == 0 && nfrac == 0) return 0;
    *next = p;
    if (ndig <= 15 && nfrac <= 22) {
        /* both exact in binary: one correctly rounded division, as strtod would give */
        double v = nfrac ? (double)mant / POW10[nfrac] : (double)mant;
        *out = neg ? -v : v;
        return 1;
    }
    char tmp[80];
    size_t n = (size_t)(p - s);
    if (n >= sizeof tmp) return 0;
    memcpy(tmp, s, n);
    tmp[n] = 0;
    *out = strtod(tmp, NULL);
    return 1;
}

/* m / 10^dec (m >= 0) with dec decimals (no point when dec is 0); returns the end. */
static char *put_fixed(char *s, long long m, int dec) {
    /* the digits of m (>= 0) from the last, the point after dec of them: divisions by the constant
     * 10 only (a multiplication), none by 10^dec */
    unsigned long long u = (unsigned long long)m;
    char buf[48];
    int k = 0;
    for (int i = 0; i < dec; i++) { buf[k++] = (char)('0' + u % 10); u /= 10; }
    if (dec > 0) buf[k++] = '.';
    do { buf[k++] = (char)('0' + u % 10); u /= 10; } while (u);
    while (k) *s++ = buf[--k];
    return s;
}

/* 1 and *m when v with dec decimals is written as the digits of m (m / 10^dec is |v| rounded to
 * them; the text is then a function of m alone), 0 when printf rounds it: beyond 1e9 the rounding
 * of v * 10^dec could hide a tie (values > 100 m), and near a tie printf rounds the exact value. */
static int fixed_digits(double v, int dec, long long *m) {
    double t = v * POW10[dec];
    if (!(fabs(t) < 1e9)) return 0;
    double fl = floor(t);
    double fr = t - fl;
    if (fabs(fr - 0.5) < 1e-6) return 0;
    *m = (long long)(fr < 0.5 ? fl : fl + 1.0);
    return 1;
}

/* Python's f"{v:.{dec}f}" (dec 4 or 5), with "-0.000.." written as "0.000..". */
static int fmt_fixed_m(char *o, double v, int dec, long long *mout, int *exact) {
    long long m;
    *exact = fixed_digits(v, dec, &m);
    if (!*exact) {
        int n = sprintf(o, "%.*f", dec, v);
        if (o[0] == '-') {                        /* "-0.0000" -> "0.0000" */
            int zero = 1;
            for (int i = 1; i < n; i++) if (o[i] != '0' && o[i] != '.') { zero = 0; break; }
            if (zero) { memmove(o, o + 1, (size_t)n); n--; }
        }
        return n;
    }
    *mout = m;
    char *s = o;
    if (m < 0) { *s++ = '-'; m = -m; }
    return (int)(put_fixed(s, m, dec) - o);
}

static int fmt_fixed(char *o, double v, int dec) {
    long long m;
    int exact;
    return fmt_fixed_m(o, v, dec, &m, &exact);
}

/* The text of the last written value of each column, kept so that it is formatted once: valid while
 * the value (bit for bit) and the unit are the ones it was made from. Per thread. */
static __thread double cache_val[6];
static __thread int cache_inch[6] = {-1, -1, -1, -1, -1, -1};
static __thread char cache_txt[6][40];

static const double RAD2DEG = 180.0 / 3.14159265358979323846;

/* The number a coordinate's word shows for the position q (mm, rad): deg, inch or mm. */
static double shown(double q, int rot, int inch) {
    return rot ? RAD2DEG * q : (inch ? q / 25.4 : q);
}

/* One coordinate's text (without the letter) with dec decimals, NUL-terminated; returns its length. */
static int fmt_value(char *o, double q, int rot, int inch, int dec) {
    int n = fmt_fixed(o, shown(q, rot, inch), dec);
    o[n] = 0;
    return n;
}

/* Whether the positions a and b are written as different text with dec decimals: 1 or 0 when
 * their digits say so, -1 when only their texts can (printf rounds one of them). */
static int texts_differ(double a, double b, int rot, int inch, int dec) {
    long long ma, mb;
    if (!fixed_digits(shown(a, rot, inch), dec, &ma) || !fixed_digits(shown(b, rot, inch), dec, &mb))
        return -1;
    return ma != mb;
}

/* As fmt_value, and *back: the position the text says (mm, rad), as Python's float() of the text
 * would read it: m / 10^dec is that correctly rounded value when the digits are known exactly. */
static int fmt_value_back(char *o, double q, int rot, int inch, int dec, double *back) {
    static const double DEG2RAD_ = 3.14159265358979323846 / 180.0;
    long long m = 0;
    int exact = 0, n;
    n = fmt_fixed_m(o, shown(q, rot, inch), dec, &m, &exact);
    o[n] = 0;
    double x = exact ? (double)m / POW10[dec] : strtod(o, NULL);
    *back = rot ? x * DEG2RAD_ : (inch ? x * 25.4 : x);
    return n;
}

long long mt_process(const char *buf, long long len, int eof, long long *consumed,
                     double *state, int na, const int *letter_col, const int *is_rot,
                     const char *letters,
                     long long *r_line, double *r_start, double *r_end, double *r_feed,
                     signed char *r_dirs, unsigned char *r_rapid, unsigned char *r_known,
                     int *r_frame, long long r_cap, long long *r_n,
                     const long long *c_line, const long long *c_off, const double *c_pts,
                     long long c_n, long long *c_row,
                     char *out, long long out_cap, long long *out_n, double *last) {
    static const double DEG2RAD = 3.14159265358979323846 / 180.0;
    long long pos = *consumed;
    for (;;) {
        if (pos >= len) { *consumed = pos; return NEED_INPUT; }
        if (state[19] != 0.0) { *consumed = pos; return FALLBACK; }
        const char *ls = buf + pos;
        const char *nl = memchr(ls, '\n', (size_t)(len - pos));
        const char *raw_end;
        if (nl) raw_end = nl + 1;
        else if (eof) raw_end = buf + len;
        else { *consumed = pos; return NEED_INPUT; }
        const char *ce = raw_end;
        while (ce > ls && (ce[-1] == '\r' || ce[-1] == '\n')) ce--;
        int ending = 0;                       /* 0 none, 1 LF, 2 CRLF */
        if (raw_end > ls && raw_end[-1] == '\n')
            ending = (raw_end - ls >= 2 && raw_end[-2] == '\r') ? 2 : 1;
        if (out) {
            long long need = 4096 + 2 * (long long)(raw_end - ls);
            if (need > out_cap / 2) { *consumed = pos; return FALLBACK; }   /* huge line: Python */
            if (out_cap - *out_n < need) { *consumed = pos; return OUT_FULL; }
        }

        /* tokens */
        const char *p = ls, *n_s = 0, *n_e = 0;
        const char *ax_s[6] = {0, 0, 0, 0, 0, 0}, *ax_e[6] = {0, 0, 0, 0, 0, 0};
        int has_g = 0, g = -1, has_f = 0, nwords = 0;
        unsigned seen = 0;
        double vals[6] = {0, 0, 0, 0, 0, 0}, fval = 0.0;
        int simple = 1;
        while (p < ce) {
            char ch = *p;
            if (ch == ' ' || ch == '\t') { p++; continue; }
            if (ch == '(' || ch == ';') {            /* comments: kept, in order */
                const char *q = ce;
                if (ch == '(') {
                    q = p + 1;
                    while (q < ce && *q != ')' && *q != '(') q++;
                    if (q >= ce || *q == '(') { simple = 0; break; }
                    q++;
                }
                p = q;
                continue;
            }
            if (!is_alpha(ch)) { simple = 0; break; }
            nwords++;
            char L = (char)(ch & ~0x20);
            const char *ts = p;
            double v;
            if (!parse_num(p + 1, ce, &v, &p)) { simple = 0; break; }
            if (p < ce && !(*p == ' ' || *p == '\t' || *p == '(' || *p == ';' || is_alpha(*p))) {
                simple = 0; break;
            }
            if (L == 'N') {
                if (n_s) { simple = 0; break; }
                n_s = ts; n_e = p;
            } else if (L == 'G') {
                if (has_g || !(v == 0.0 || v == 1.0)) { simple = 0; break; }
                has_g = 1; g = (v == 1.0);
            } else if (L == 'F') {
                if (has_f || !(v > 0.0)) { simple = 0; break; }
                /* no point: a Haas reads F by its Setting 77 (word_use.py): Python (a Fanuc reads
                 * a feed per minute in whole units; G93, in thousandths, is Python's anyway) */
                if (state[25] == 2.0 && !memchr(ts, '.', (size_t)(p - ts))) { simple = 0; break; }
                has_f = 1; fval = v;
            } else if (L == 'X' || L == 'Y' || L == 'Z' || L == 'A' || L == 'B' || L == 'C') {
                int col = letter_col[L - 'A'];
                if (col < 0 || (seen & (1u << col))) { simple = 0; break; }
                const char *dot = memchr(ts, '.', (size_t)(p - ts));
                if (dot && p - dot - 1 > 15) { simple = 0; break; }   /* more decimals: Python */
                /* no point: Fanuc and Haas read the least input increment (word_use.py): Python */
                if (!dot && v != 0.0 && (state[25] != 0.0 || leading_zero(ts + 1, p))) {
                    simple = 0; break;      /* leading zeros (X0019685): fixed format, Python */
                }
                seen |= 1u << col;
                vals[col] = v;
                ax_s[col] = ts; ax_e[col] = p;
            } else if (L == 'I' || L == 'J' || L == 'K' || L == 'R' || L == 'U' || L == 'V' ||
                       L == 'W') {
                simple = 0; break;                  /* arcs and foreign axes: Python decides */
            } else if (L == 'D' || L == 'E' || L == 'H' || L == 'L' || L == 'P' || L == 'Q') {
                simple = 0; break;          /* value words: whether a code uses them is Python's */
            } else if (L == 'O' || L == 'T' || (L == 'M' && (v == 2.0 || v == 30.0 || v == 6.0 || v == 97.0 || v == 98.0 || v == 99.0 || v == 128.0 || v == 428.0 ||
                                          v == 430.0))) {
                simple = 0; break;          /* program numbers, tool changes, subprograms: Python */
            }                                       /* M S ...: kept as written */
        }
        if (!simple) { *consumed = pos; return FALLBACK; }
        int motion = has_g ? g : (int)state[13];
        int inch = state[14] != 0.0;
        if (seen && !(motion == 0 || motion == 1)) { *consumed = pos; return FALLBACK; }
        unsigned known = (unsigned)state[20];
        /* an incremental move of an axis not known: Python refuses it */
        if (seen && state[15] != 0.0 && (seen & ~known)) { *consumed = pos; return FALLBACK; }
        /* the writer keeps an incremental line incremental: Python writes it */
        if (out && seen && state[15] != 0.0) { *consumed = pos; return FALLBACK; }
        long long line_no = (long long)state[16] + 1;
        if (seen) {
            if (r_line && *r_n >= r_cap) { *consumed = pos; return ROWS_FULL; }
            if (out) {
                if (*c_row >= c_n) { *consumed = pos; return NEED_CORR; }
                if (c_line[*c_row] != line_no) { *consumed = pos; return MISMATCH; }
                long long need = (c_off[*c_row + 1] - c_off[*c_row]) * (na * 128 + 16) + 512
                                 + (long long)(raw_end - ls);
                if (need > out_cap / 2) { *consumed = pos; return FALLBACK; }   /* huge: Python */
                if (out_cap - *out_n < need) { *consumed = pos; return OUT_FULL; }
            }
        }
        /* the line is ours: update the state */
        if (has_f) state[12] = fval * (inch ? 25.4 : 1.0);
        if (has_g) state[13] = (double)g;
        if (seen) {
            double start[6], end[6];
            double scale = inch ? 25.4 : 1.0;
            int incr = state[15] != 0.0;
            for (int j = 0; j < na; j++) { start[j] = state[j]; end[j] = state[j]; }
            for (int j = 0; j < na; j++) {
                if (!(seen & (1u << j))) continue;
                double v = is_rot[j] ? vals[j] * DEG2RAD : vals[j] * scale;
                end[j] = incr ? start[j] + v : v;
            }
            /* a start the program has not given on every axis: bit 7 of the row's known mask */
            unsigned all = (1u << na) - 1u;
            unsigned jump = (known & all) != all ? 128u : 0u;
            unsigned fresh = seen & ~known;   /* moved from a position not given: direction unknown */
            known |= seen;
            state[20] = (double)known;
            for (int j = 0; j < na; j++) {    /* selects, not branches: the signs vary */
                double step = end[j] - start[j], d = state[6 + j];
                d = step > 1e-9 ? 1.0 : d;
                d = step < -1e-9 ? -1.0 : d;
                state[6 + j] = (fresh & (1u << j)) ? 0.0 : d;
                state[j] = end[j];
            }
            if (r_line) {
                long long r = *r_n;
                r_line[r] = line_no;
                for (int j = 0; j < na; j++) {
                    r_start[r * na + j] = start[j];
                    r_end[r * na + j] = end[j];
                    r_dirs[r * na + j] = (signed char)state[6 + j];
                }
                r_feed[r] = motion == 0 ? NAN : state[12];
                r_rapid[r] = (unsigned char)(motion == 0);
                r_known[r] = (unsigned char)(known | jump);
                r_frame[r] = (int)state[21];
                *r_n = r + 1;
            }
            if (out) {
                long long row = *c_row;
                char *o = out + *out_n;
                const char *sep = ending == 2 ? "\r\n" : ending == 1 ? "\n"
                                  : (state[18] != 0.0 ? "\r\n" : "\n");
                size_t sl = strlen(sep);
                if (ending) state[18] = (ending == 2);
                int incr = state[15] != 0.0;
                /* the line's style: blank between words or none, letter case of its first axis word */
                int blank = nwords < 2 || memchr(ls, ' ', (size_t)(ce - ls)) || memchr(ls, '\t', (size_t)(ce - ls));
                const char *first_ax = 0, *last_ax_e = 0;
                int line_dec = 0, own_dec[6] = {0, 0, 0, 0, 0, 0};
                for (int j = 0; j < na; j++) {
                    if (!(seen & (1u << j))) continue;
                    if (!first_ax || ax_s[j] < first_ax) first_ax = ax_s[j];
                    if (!last_ax_e || ax_e[j] > last_ax_e) last_ax_e = ax_e[j];
                    const char *dot = memchr(ax_s[j], '.', (size_t)(ax_e[j] - ax_s[j]));
                    own_dec[j] = dot ? (int)(ax_e[j] - dot - 1) : 0;
                    if (own_dec[j] > line_dec) line_dec = own_dec[j];
                }
                int lower = first_ax && *first_ax >= 'a';
                char gl = lower ? 'g' : 'G';
                int dec[6];
                for (int j = 0; j < na; j++) {
                    int base = (!is_rot[j] && inch) ? 5 : 4;
                    int d = (seen & (1u << j)) ? own_dec[j] : line_dec;
                    dec[j] = d > base ? d : base;
                }
                /* edits of the first piece: (start, end, kind, text): 0 head, 1 number, 2 added */
                char ebuf[2048];
                int eb = 0, ne = 0;
                const char *es[10], *ee[10];
                int ek[10], eo[10], el[10];
                {   /* head: G90 where the output is in G91, the motion word where its mode differs */
                    int h0 = eb;
                    if (state[17] == 0.0) {
                        if (n_s && blank) ebuf[eb++] = ' ';
                        ebuf[eb++] = gl; ebuf[eb++] = '9'; ebuf[eb++] = '0';
                        state[17] = 1.0;
                    }
                    if (!has_g && state[22] != (double)motion) {
                        if ((eb > h0 || n_s) && blank) ebuf[eb++] = ' ';
                        ebuf[eb++] = gl; ebuf[eb++] = (char)('0' + motion);
                    }
                    state[22] = (double)motion;
                    if (eb > h0) {
                        const char *at = n_s ? n_e : ls;
                        if (!n_s) {
                            while (at < ce && (*at == ' ' || *at == '\t')) at++;
                            if (blank) ebuf[eb++] = ' ';
                        }
                        es[ne] = at; ee[ne] = at; ek[ne] = 0; eo[ne] = h0; el[ne] = eb - h0; ne++;
                    }
                }
                char tmp[64], nom[64];
                long long k0 = c_off[row], k1 = c_off[row + 1];
                char abuf[1024];
                int ab = 0;
                for (long long k = k0; k < k1; k++) {
                    int first = (k == k0);
                    const double *q = c_pts + k * na;
                    char *mark = o;
                    int wrote = 0;
                    if (!first) { memcpy(o, sep, sl); o += sl; }
                    for (int j = 0; j < na; j++) {
                        if (!(known & (1u << j))) continue;
                        int base = (!is_rot[j] && inch) ? 5 : 4;
                        int named = first && (seen & (1u << j));
                        double back;
                        if (named) {
                            if (!incr && q[j] == end[j]) { last[j] = end[j]; continue; }
                            /* a correction that leaves the word's text as it is: nothing to write */
                            int differ = incr ? 1 : texts_differ(q[j], end[j], is_rot[j], inch, dec[j]);
                            if (!differ) { last[j] = end[j]; continue; }
                            int tn = fmt_value_back(tmp, q[j], is_rot[j], inch, dec[j], &back);
                            if (differ < 0) {
                                fmt_value(nom, end[j], is_rot[j], inch, dec[j]);
                                if (strcmp(tmp, nom) == 0) { last[j] = end[j]; continue; }
                            }
                            es[ne] = ax_s[j] + 1; ee[ne] = ax_e[j]; ek[ne] = 1; eo[ne] = eb; el[ne] = tn;
                            memcpy(ebuf + eb, tmp, (size_t)tn); eb += tn; ne++;
                        } else {
                            if (q[j] == last[j]) continue;          /* the same value: the same text */
                            int tn = fmt_value_back(tmp, q[j], is_rot[j], inch, base, &back);
                            if (!isnan(last[j])) {
                                if (cache_inch[j] != inch || memcmp(&cache_val[j], &last[j], sizeof(double))) {
                                    fmt_value(cache_txt[j], last[j], is_rot[j], inch, base);
                                    cache_val[j] = last[j];
                                    cache_inch[j] = inch;
                                }
                                if (strcmp(tmp, cache_txt[j]) == 0) continue;
                            }
                            if (dec[j] != base) tn = fmt_value_back(tmp, q[j], is_rot[j], inch, dec[j], &back);
                            char L = lower ? (char)(letters[j] | 0x20) : letters[j];
                            if (first) {        /* added after the line's last axis word */
                                if (blank) abuf[ab++] = ' ';
                                abuf[ab++] = L;
                                memcpy(abuf + ab, tmp, (size_t)tn); ab += tn;
                            } else {
                                if (wrote && blank) *o++ = ' ';
                                *o++ = L;
                                memcpy(o, tmp, (size_t)tn); o += tn;
                                wrote = 1;
                            }
                        }
                        last[j] = back;
                        if (dec[j] == base && !named) {   /* its text is the one just made */
                            memcpy(cache_txt[j], tmp, strlen(tmp) + 1);
                            cache_val[j] = last[j];
                            cache_inch[j] = inch;
                        } else cache_inch[j] = -1;
                    }
                    if (first) {
                        if (ab) {
                            state[23] += 1.0;
                            if (state[24] == 0.0) state[24] = (double)line_no;
                            memcpy(ebuf + eb, abuf, (size_t)ab);
                            es[ne] = last_ax_e; ee[ne] = last_ax_e; ek[ne] = 2; eo[ne] = eb; el[ne] = ab;
                            eb += ab; ne++;
                        }
                        /* the source line with its edits, in the order of their places */
                        for (int a = 1; a < ne; a++) {
                            for (int b = a; b > 0 && (es[b] < es[b - 1] || (es[b] == es[b - 1] && ek[b] < ek[b - 1])); b--) {
                                const char *t1 = es[b]; es[b] = es[b - 1]; es[b - 1] = t1;
                                t1 = ee[b]; ee[b] = ee[b - 1]; ee[b - 1] = t1;
                                int t2 = ek[b]; ek[b] = ek[b - 1]; ek[b - 1] = t2;
                                t2 = eo[b]; eo[b] = eo[b - 1]; eo[b - 1] = t2;
                                t2 = el[b]; el[b] = el[b - 1]; el[b - 1] = t2;
                            }
                        }
                        const char *src = ls;
                        for (int a = 0; a < ne; a++) {
                            memcpy(o, src, (size_t)(es[a] - src)); o += es[a] - src;
                            memcpy(o, ebuf + eo[a], (size_t)el[a]); o += el[a];
                            src = ee[a];
                        }
                        memcpy(o, src, (size_t)(ce - src)); o += ce - src;
                    } else if (!wrote) o = mark;      /* a later piece that changes nothing */
                }
                if (ending == 2) { *o++ = '\r'; *o++ = '\n'; }
                else if (ending == 1) *o++ = '\n';
                *out_n = o - out;
                *c_row = row + 1;
            }
        } else if (out) {
            memcpy(out + *out_n, ls, (size_t)(raw_end - ls));
            *out_n += raw_end - ls;
            if (has_g) state[22] = (double)g;       /* "G1 F100" passed through */
        }
        state[16] = (double)line_no;
        pos = raw_end - buf;
    }
}

/* Python's "%.{dec}f" % v, sign kept ("-0.0000" stays), "nan", "inf", "-inf" as Python writes them.
 * Away from a tie of the last digit (by 1e-6 of it) the rounding of |v| * 10^dec, below 1e9, is
 * decided exactly; at a tie, or beyond, printf rounds the exact value (as Python does). */
static int fmt_py_fixed(char *o, double v, int dec) {
    if (isnan(v)) { memcpy(o, "nan", 3); return 3; }
    if (isinf(v)) { if (v < 0) { memcpy(o, "-inf", 4); return 4; } memcpy(o, "inf", 3); return 3; }
    double t = fabs(v) * POW10[dec];
    double fl = floor(t);
    double fr = t - fl;
    if (!(t < 1e9) || fabs(fr - 0.5) < 1e-6) return sprintf(o, "%.*f", dec, v);
    long long m = (long long)(fr < 0.5 ? fl : fl + 1.0);
    char *s = o;
    if (signbit(v)) *s++ = '-';
    return (int)(put_fixed(s, m, dec) - o);
}

/* Rows of a CSV table: vals (n, k) row-major; per column dec[j] >= 0 writes "%.{dec}f" % v (0 to
 * 6 decimals), dec[j] < 0 an empty field; blank[j] != 0 writes an empty field for a NaN or an
 * infinity. Each row ends with '\n'. Returns the bytes written, or -1 when cap is too small. */
long long mt_format_table(const double *vals, long long n, int k, const int *dec, const int *blank,
                          char *out, long long cap) {
    char *o = out, *end = out + cap;
    for (long long i = 0; i < n; i++) {
        const double *row = vals + i * k;
        for (int j = 0; j < k; j++) {
            if (end - o < 400) return -1;           /* room for the longest printf of a double */
            if (j) *o++ = ',';
            if (dec[j] < 0 || (blank[j] && !isfinite(row[j]))) continue;
            o += fmt_py_fixed(o, row[j], dec[j] > 6 ? 6 : dec[j]);
        }
        if (o >= end) return -1;
        *o++ = '\n';
    }
    return (long long)(o - out);
}

/* The codes of mt_g_codes that the letter at text[i] starts (set in found), how many new. */
static int g_word_at(const char *text, long long len, long long i, const char *codes, int n_codes,
                     int *found) {
    char after[6];
    int added = 0;
    for (int j = 0; j < 6; j++) after[j] = i + 1 + j < len ? text[i + 1 + j] : ' ';
    for (int k = 0; k < n_codes; k++) {
        if (found[k]) continue;
        for (int zeros = 0; zeros < 3; zeros++) {
            int z = 0;
            while (z < zeros && after[z] == '0') z++;
            if (z < zeros) break;
            char next = after[zeros + 2];
            if (after[zeros] == codes[2 * k] && after[zeros + 1] == codes[2 * k + 1]
                && !is_digit(next) && next != '.') {
                found[k] = 1;
                added++;
                break;
            }
        }
    }
    return added;
}

/* Which of the n_codes two-digit G codes (codes: their digits one after the other, "20214142")
 * the first len bytes of text hold: G or g, at most two zeros, the code, not followed by a digit or
 * '.' (a byte at or past len reads as a space). found[k] is set to 1 for each code found; those
 * already set are not looked for. Returns how many are set. (compensation._g_codes in numpy.) */
int mt_g_codes(const char *text, long long len, const char *codes, int n_codes, int *found) {
    int left = 0;
    for (int k = 0; k < n_codes; k++) left += !found[k];
    for (int letter = 0; letter < 2 && left; letter++) {     /* the G words, then the g words */
        const char *p = text, *end = text + len;
        while (left && (p = memchr(p, letter ? 'g' : 'G', (size_t)(end - p))) != NULL) {
            left -= g_word_at(text, len, p - text, codes, n_codes, found);
            p++;
        }
    }
    int n = 0;
    for (int k = 0; k < n_codes; k++) n += found[k] != 0;
    return n;
}
