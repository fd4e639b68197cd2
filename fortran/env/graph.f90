!> The parts of a square matrix that do not act on each other: the connected components of
!> the graph whose edges are its nonzero entries.
module pymr_env_graph
  use pymr_env_kinds, only : dp
  implicit none
  private
  public :: connected_parts

contains

  !> Part number of each row and column of the square matrix a (1, 2, ... in the order of
  !> each part's first row): i and j share a part when a chain of nonzero entries a(i, k),
  !> a(k, l), ... (either way round) joins them. Union-find over the entries, each part's
  !> root its first row.
  pure function connected_parts(a) result(part)
    real(dp), intent(in) :: a(:, :)
    integer :: part(size(a, 1))
    integer :: root(size(a, 1)), i, j, ri, rj, n, np
    n = size(a, 1)
    root = [(i, i = 1, n)]
    do j = 1, n
      do i = 1, n
        if (a(i, j) == 0.0_dp .or. i == j) cycle
        ri = top(i); rj = top(j)
        root(i) = ri; root(j) = rj          ! the next search from i or j is one step
        if (ri /= rj) root(max(ri, rj)) = min(ri, rj)
      end do
    end do
    np = 0
    do i = 1, n
      ri = top(i)
      if (ri == i) then
        np = np + 1; part(i) = np
      else
        part(i) = part(ri)
      end if
    end do
  contains
    pure integer function top(k)
      integer, intent(in) :: k
      top = k
      do while (root(top) /= top)
        top = root(top)
      end do
    end function top
  end function connected_parts
end module pymr_env_graph
