/* solve6: the 6 x 6 linear solve shared by the C kernels (the IK's step in
 * native/_ik_core.h, the contact wrench in fci/contact/_contact.c). */
#ifndef FRANKA_SIM_GYM_SOLVE6_H
#define FRANKA_SIM_GYM_SOLVE6_H

#include <math.h>

/* Solve the 6x6 system A x = b in place (Gaussian elimination, partial pivoting, as
 * LAPACK's gesv does); b becomes x. A singular matrix gives inf / NaN, as there. */
static void solve6(double A[6][6], double b[6])
{
    for (int c = 0; c < 6; c++) {
        int pivot = c;
        for (int r = c + 1; r < 6; r++)
            if (fabs(A[r][c]) > fabs(A[pivot][c])) pivot = r;
        if (pivot != c) {
            for (int k = 0; k < 6; k++) {
                double t = A[c][k];
                A[c][k] = A[pivot][k];
                A[pivot][k] = t;
            }
            double t = b[c];
            b[c] = b[pivot];
            b[pivot] = t;
        }
        for (int r = c + 1; r < 6; r++) {
            double f = A[r][c] / A[c][c];
            for (int k = c; k < 6; k++) A[r][k] -= f * A[c][k];
            b[r] -= f * b[c];
        }
    }
    for (int r = 5; r >= 0; r--) {
        double s = b[r];
        for (int k = r + 1; k < 6; k++) s -= A[r][k] * b[k];
        b[r] = s / A[r][r];
    }
}

#endif
