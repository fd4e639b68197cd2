!> Symbolic sparse Cholesky: the elimination tree and the column counts of the factor L of a
!> symmetric matrix, from its pattern alone. `pymr modal-import` uses the counts to tell the
!> memory (8 bytes an entry of L) and the work (sum of the squared counts) of a sparse
!> factorisation before it is made. Liu's algorithms (as in Davis, Direct Methods for
!> Sparse Linear Systems, 2006, sections 4.1 and 4.2): the tree with path compression, the
!> counts from the row subtrees, O(nnz(L)) time and O(n) extra memory.
module pymr_env_sparse_cholesky
  implicit none
  private
  public :: elimination_tree, column_counts
contains
  !> Parent of each column in the elimination tree (0 at a root). The pattern is that of
  !> the whole symmetric matrix (both triangles), 1-based compressed columns.
  pure subroutine elimination_tree(n, colptr, rowind, parent)
    integer, intent(in) :: n, colptr(n + 1), rowind(:)
    integer, intent(out) :: parent(n)
    integer :: ancestor(n), k, p, r, next
    parent = 0; ancestor = 0
    do k = 1, n
      do p = colptr(k), colptr(k + 1) - 1
        r = rowind(p)
        do while (r /= 0 .and. r < k)
          next = ancestor(r)
          ancestor(r) = k
          if (next == 0) parent(r) = k
          r = next
        end do
      end do
    end do
  end subroutine elimination_tree

  !> Entries of each column of L, its diagonal included: row k of L holds the columns of
  !> the row subtree of k, the tree paths from each i < k with a(k, i) /= 0 up to k.
  pure subroutine column_counts(n, colptr, rowind, parent, counts)
    integer, intent(in) :: n, colptr(n + 1), rowind(:), parent(n)
    integer, intent(out) :: counts(n)
    integer :: mark(n), k, p, i
    counts = 1; mark = 0
    do k = 1, n
      mark(k) = k
      do p = colptr(k), colptr(k + 1) - 1
        i = rowind(p)
        if (i >= k) cycle
        do while (mark(i) /= k)
          counts(i) = counts(i) + 1
          mark(i) = k
          i = parent(i)
        end do
      end do
    end do
  end subroutine column_counts
end module pymr_env_sparse_cholesky
