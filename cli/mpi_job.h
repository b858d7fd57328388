/* The CLI's side of a distributed job (docs/distributed.md): the processes
 * (ranks) that mpirun or srun started together, and the work they divide.
 * Built with MPI when CMake finds it (LU_HAVE_MPI); without it every call
 * answers as a job of one process, so the commands need no #ifdef. The
 * library knows nothing of MPI: ranks divide a frame through
 * lu_renderer_render_rows. MPI is called from the main thread only. */
#ifndef LU_CLI_MPI_JOB_H
#define LU_CLI_MPI_JOB_H

#include <lucent/lucent.h>

/* Rows per band handed out by the work queue, by default: a multiple of the
 * 16-pixel tiles of bssrdf and ddod, so no tile is rendered by two ranks. */
#define LU_MPI_BAND_ROWS 16

/* Joins the job when a launcher started this process (its environment says
 * so); otherwise, and without MPI, a job of one. Without LUCENT_THREADS, a
 * rank's thread count is the node's processors divided among the ranks on
 * that node. Returns LU_EXIT_OK or an exit code after a message. */
int lu_mpi_begin(int *argc, char ***argv);
/* Leaves the job. rc != 0 on any rank of a job of several ends the whole
 * job (MPI_Abort with rc; it does not return): the other ranks may be
 * waiting for this one, and no rank may write an output after a failure. */
int lu_mpi_end(int rc);
int lu_mpi_rank(void);
int lu_mpi_size(void);   /* 1: not distributed */

/* Renders one frame divided among the ranks: bands of rows_per_band rows
 * (0: LU_MPI_BAND_ROWS)
 * from a work queue on rank 0 (every rank renders, rank 0 too), gathered on
 * rank 0, whose *out then holds the whole image, bit for bit what
 * lu_renderer_render gives; the other ranks' *out is partial. On rank 0, a
 * progress bar of the bands done by all ranks, and (label non-NULL) one line
 * per rank: its global stages and its bands. */
lu_result lu_mpi_render(lu_renderer *r, const lu_scene *scene, lu_image *out, int rows_per_band, const char *label,
                        lu_error *err);

/* A work queue over `count` items (bench's scenes): the next item for this
 * rank, or -1 when all are taken. One queue at a time, opened by every rank
 * with the same count and closed by every rank. */
lu_result lu_mpi_queue_open(int count, lu_error *err);
int lu_mpi_queue_next(void);
void lu_mpi_queue_close(void);

/* One image from this rank to rank 0 (with a number that travels along,
 * e.g. its render time), and rank 0's receipt of the next one from rank
 * `from`, into *img (created or resized as needed). Both wait asleep, not
 * polling a processor away from ranks still rendering. */
lu_result lu_mpi_send_image(const lu_image *img, double value, lu_error *err);
lu_result lu_mpi_recv_image(int from, lu_image *img, double *value, lu_error *err);

/* Gathers each rank's `bytes` bytes on rank 0 in rank order: *all (freed
 * with free) and *total there; NULL and 0 on the others. */
lu_result lu_mpi_gather(const void *data, size_t bytes, void **all, size_t *total, lu_error *err);

#endif
