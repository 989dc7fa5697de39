"""The C source of the fixed-order matrix product (fixed_order.py compiles it on first use).

It lives in a Python module so that it is part of the import closure of every stage that trains or
predicts: editing it changes those stages' code fingerprints and re-runs them, as editing any of
their Python modules does (pipeline/codedeps.py).
"""

SOURCE = r"""/* Fixed-order single-precision matrix product for the portable kernels (tool/model/fixed_order.py).

   C[i,j] = fma(A[i,K-1], B[K-1,j], ... fma(A[i,1], B[1,j], fma(A[i,0], B[0,j], 0)))

   Every output element is one chain of fused multiply-adds over k in increasing order. Vector lanes
   (and the 6x16 register tile) split only the output elements, and a chain that crosses a K block
   resumes from the stored, already rounded value, which is what it would have held in a register.
   So the bytes depend neither on the blocking nor on the vector width: every x86-64 CPU with AVX2 and
   FMA computes the same bits (fma is correctly rounded by IEEE 754). Build: -O2 -mavx2 -mfma
   -ffp-contract=off, no -ffast-math (nothing may be reassociated or contracted). */

#include <immintrin.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MR 6
#define NR 16
#define KC 256
#define MC 96

/* t (MR rows of NR floats, row stride ldt) += the kc-step chains; load == 0 starts them from 0 */
static void kernel_6x16(long kc, const float *a, const float *b, float *t, long ldt, int load)
{
    __m256 c00, c01, c10, c11, c20, c21, c30, c31, c40, c41, c50, c51;
    if (load) {
        c00 = _mm256_loadu_ps(t + 0 * ldt); c01 = _mm256_loadu_ps(t + 0 * ldt + 8);
        c10 = _mm256_loadu_ps(t + 1 * ldt); c11 = _mm256_loadu_ps(t + 1 * ldt + 8);
        c20 = _mm256_loadu_ps(t + 2 * ldt); c21 = _mm256_loadu_ps(t + 2 * ldt + 8);
        c30 = _mm256_loadu_ps(t + 3 * ldt); c31 = _mm256_loadu_ps(t + 3 * ldt + 8);
        c40 = _mm256_loadu_ps(t + 4 * ldt); c41 = _mm256_loadu_ps(t + 4 * ldt + 8);
        c50 = _mm256_loadu_ps(t + 5 * ldt); c51 = _mm256_loadu_ps(t + 5 * ldt + 8);
    } else {
        c00 = c01 = c10 = c11 = c20 = c21 = c30 = c31 = c40 = c41 = c50 = c51 = _mm256_setzero_ps();
    }
    for (long k = 0; k < kc; k++) {
        __m256 b0 = _mm256_load_ps(b), b1 = _mm256_load_ps(b + 8), x;
        x = _mm256_broadcast_ss(a + 0); c00 = _mm256_fmadd_ps(x, b0, c00); c01 = _mm256_fmadd_ps(x, b1, c01);
        x = _mm256_broadcast_ss(a + 1); c10 = _mm256_fmadd_ps(x, b0, c10); c11 = _mm256_fmadd_ps(x, b1, c11);
        x = _mm256_broadcast_ss(a + 2); c20 = _mm256_fmadd_ps(x, b0, c20); c21 = _mm256_fmadd_ps(x, b1, c21);
        x = _mm256_broadcast_ss(a + 3); c30 = _mm256_fmadd_ps(x, b0, c30); c31 = _mm256_fmadd_ps(x, b1, c31);
        x = _mm256_broadcast_ss(a + 4); c40 = _mm256_fmadd_ps(x, b0, c40); c41 = _mm256_fmadd_ps(x, b1, c41);
        x = _mm256_broadcast_ss(a + 5); c50 = _mm256_fmadd_ps(x, b0, c50); c51 = _mm256_fmadd_ps(x, b1, c51);
        a += MR;
        b += NR;
    }
    _mm256_storeu_ps(t + 0 * ldt, c00); _mm256_storeu_ps(t + 0 * ldt + 8, c01);
    _mm256_storeu_ps(t + 1 * ldt, c10); _mm256_storeu_ps(t + 1 * ldt + 8, c11);
    _mm256_storeu_ps(t + 2 * ldt, c20); _mm256_storeu_ps(t + 2 * ldt + 8, c21);
    _mm256_storeu_ps(t + 3 * ldt, c30); _mm256_storeu_ps(t + 3 * ldt + 8, c31);
    _mm256_storeu_ps(t + 4 * ldt, c40); _mm256_storeu_ps(t + 4 * ldt + 8, c41);
    _mm256_storeu_ps(t + 5 * ldt, c50); _mm256_storeu_ps(t + 5 * ldt + 8, c51);
}

/* B[k0:k0+kc, j0:j0+NR] -> kc rows of NR floats (columns past n padded with zeros) */
static void pack_b(long kc, long n, const float *b, long sk, long sn, float *out)
{
    if (sk == 1 && sn != 1) {                       /* B transposed in memory: read each column in order */
        for (long j = 0; j < n; j++) {
            const float *col = b + j * sn;
            for (long k = 0; k < kc; k++) out[k * NR + j] = col[k];
        }
        for (long k = 0; k < kc; k++)
            for (long j = n; j < NR; j++) out[k * NR + j] = 0.0f;
        return;
    }
    for (long k = 0; k < kc; k++, out += NR) {
        const float *row = b + k * sk;
        long j = 0;
        if (sn == 1)
            for (; j < n; j++) out[j] = row[j];
        else
            for (; j < n; j++) out[j] = row[j * sn];
        for (; j < NR; j++) out[j] = 0.0f;
    }
}

/* A[i0:i0+MR, k0:k0+kc] -> kc columns of MR floats (rows past m padded with zeros) */
static void pack_a(long kc, long m, const float *a, long sm, long sk, float *out)
{
    if (m == MR && sk == 1) {                       /* six rows, each read in order */
        const float *r0 = a, *r1 = a + sm, *r2 = a + 2 * sm, *r3 = a + 3 * sm, *r4 = a + 4 * sm, *r5 = a + 5 * sm;
        for (long k = 0; k < kc; k++, out += MR) {
            out[0] = r0[k]; out[1] = r1[k]; out[2] = r2[k]; out[3] = r3[k]; out[4] = r4[k]; out[5] = r5[k];
        }
        return;
    }
    if (m == MR && sm == 1) {                       /* A transposed in memory: six floats in a row per k */
        for (long k = 0; k < kc; k++, out += MR) {
            const float *col = a + k * sk;
            out[0] = col[0]; out[1] = col[1]; out[2] = col[2]; out[3] = col[3]; out[4] = col[4]; out[5] = col[5];
        }
        return;
    }
    for (long k = 0; k < kc; k++, out += MR) {
        long i = 0;
        for (; i < m; i++) out[i] = a[i * sm + k * sk];
        for (; i < MR; i++) out[i] = 0.0f;
    }
}

/* C = A B with A (m x k, strides sam, sak), B (k x n, strides sbk, sbn), C (m x n, strides scm, scn).
   Returns 0, or -1 if the packing buffers could not be allocated. */
int fo_gemm(long m, long n, long k, const float *a, long sam, long sak, const float *b, long sbk, long sbn,
            float *c, long scm, long scn)
{
    long np = (n + NR - 1) / NR;
    long kc_max = k < KC ? k : KC;
    float *bp = aligned_alloc(64, sizeof(float) * (size_t)(np * NR * (kc_max > 0 ? kc_max : 1)));
    float *ap = aligned_alloc(64, sizeof(float) * (size_t)(MC * (kc_max > 0 ? kc_max : 1)));
    float t[MR * NR] __attribute__((aligned(64)));
    if (!bp || !ap) { free(bp); free(ap); return -1; }
    if (k == 0) {
        for (long i = 0; i < m; i++)
            for (long j = 0; j < n; j++) c[i * scm + j * scn] = 0.0f;
    }
    for (long p0 = 0; p0 < k; p0 += KC) {            /* K blocks in increasing order: each chain resumes */
        long kc = k - p0 < KC ? k - p0 : KC;
        for (long jp = 0; jp < np; jp++) {
            long nn = n - jp * NR < NR ? n - jp * NR : NR;
            pack_b(kc, nn, b + p0 * sbk + jp * NR * sbn, sbk, sbn, bp + jp * NR * kc);
        }
        for (long i0 = 0; i0 < m; i0 += MC) {
            long mc = m - i0 < MC ? m - i0 : MC;
            for (long ir = 0; ir < mc; ir += MR) {
                long mm = mc - ir < MR ? mc - ir : MR;
                pack_a(kc, mm, a + (i0 + ir) * sam + p0 * sak, sam, sak, ap + ir * kc);
            }
            for (long jp = 0; jp < np; jp++) {
                long nn = n - jp * NR < NR ? n - jp * NR : NR;
                for (long ir = 0; ir < mc; ir += MR) {
                    long mm = mc - ir < MR ? mc - ir : MR;
                    float *ct = c + (i0 + ir) * scm + jp * NR * scn;
                    if (mm == MR && nn == NR && scn == 1) {     /* a whole tile: straight from and to C */
                        kernel_6x16(kc, ap + ir * kc, bp + jp * NR * kc, ct, scm, p0 > 0);
                        continue;
                    }
                    for (long i = 0; i < MR; i++)
                        for (long j = 0; j < NR; j++)
                            t[i * NR + j] = (p0 > 0 && i < mm && j < nn) ? ct[i * scm + j * scn] : 0.0f;
                    kernel_6x16(kc, ap + ir * kc, bp + jp * NR * kc, t, NR, 1);
                    for (long i = 0; i < mm; i++)
                        for (long j = 0; j < nn; j++) ct[i * scm + j * scn] = t[i * NR + j];
                }
            }
        }
    }
    free(bp);
    free(ap);
    return 0;
}

/* im2col of an NHWC tensor x (any strides): cols is (b*ho*wo) rows of kh*kw*c floats, taps outer,
   channels inner; a tap outside the image is 0. Copies only: no arithmetic. */
void fo_im2col(long b, long h, long w, long c, const float *x, long sxb, long sxh, long sxw, long sxc,
               long kh, long kw, long sy, long sx, long py, long px, long ho, long wo, float *cols)
{
    for (long n = 0; n < b; n++)
        for (long oy = 0; oy < ho; oy++)
            for (long ox = 0; ox < wo; ox++)
                for (long i = 0; i < kh; i++) {
                    long iy = oy * sy + i - py;
                    for (long j = 0; j < kw; j++, cols += c) {
                        long ix = ox * sx + j - px;
                        if (iy < 0 || iy >= h || ix < 0 || ix >= w) { memset(cols, 0, sizeof(float) * c); continue; }
                        const float *src = x + n * sxb + iy * sxh + ix * sxw;
                        if (sxc == 1) memcpy(cols, src, sizeof(float) * c);
                        else for (long ch = 0; ch < c; ch++) cols[ch] = src[ch * sxc];
                    }
                }
}

/* col2im: gx (b, h, w, c), contiguous NHWC, from the columns' gradient gc (b*ho*wo rows of kh*kw*c).
   Each element starts from 0 and adds the taps that read it in increasing (i, j) order, one IEEE
   addition each: the order in which a zero tensor receives one strided addition per tap. */
void fo_col2im(long b, long h, long w, long c, const float *gc, long kh, long kw, long sy, long sx, long py,
               long px, long ho, long wo, float *gx)
{
    long row = kh * kw * c;
    for (long n = 0; n < b; n++)
        for (long y = 0; y < h; y++)
            for (long x = 0; x < w; x++, gx += c) {
                for (long ch = 0; ch < c; ch++) gx[ch] = 0.0f;
                for (long i = 0; i < kh; i++) {
                    long ty = y + py - i;
                    if (ty < 0 || ty % sy) continue;
                    long oy = ty / sy;
                    if (oy >= ho) continue;
                    for (long j = 0; j < kw; j++) {
                        long tx = x + px - j;
                        if (tx < 0 || tx % sx) continue;
                        long ox = tx / sx;
                        if (ox >= wo) continue;
                        const float *src = gc + ((n * ho + oy) * wo + ox) * row + (i * kw + j) * c;
                        for (long ch = 0; ch < c; ch++) gx[ch] = gx[ch] + src[ch];
                    }
                }
            }
}

/* out[j] = column j's sum over the rows of g (rows x n, strides sr, sn), from 0 in row order: the chain
   fma(1, g[r, j], acc) of the product with a row of ones, which is the plain addition acc + g[r, j]. */
void fo_colsum(long rows, long n, const float *g, long sr, long sn, float *out)
{
    for (long j = 0; j < n; j++) out[j] = 0.0f;
    for (long r = 0; r < rows; r++, g += sr) {
        if (sn == 1) for (long j = 0; j < n; j++) out[j] = out[j] + g[j];
        else for (long j = 0; j < n; j++) out[j] = out[j] + g[j * sn];
    }
}

/* The same chains, one element at a time: the definition the blocked product must match bit for bit. */
void fo_gemm_reference(long m, long n, long k, const float *a, long sam, long sak, const float *b, long sbk,
                       long sbn, float *c, long scm, long scn)
{
    for (long i = 0; i < m; i++)
        for (long j = 0; j < n; j++) {
            float acc = 0.0f;
            for (long p = 0; p < k; p++) acc = fmaf(a[i * sam + p * sak], b[p * sbk + j * sbn], acc);
            c[i * scm + j * scn] = acc;
        }
}
"""
